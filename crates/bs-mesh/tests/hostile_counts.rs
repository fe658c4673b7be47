//! A count in a file that claims far more items than the file can hold (2·10⁹ nodes, a
//! 4·10⁹-id GENERATE range, a 2·10⁹-byte block…) is a clear error, found before any
//! allocation sized by the count, and fast. One test per reader; the binary `.msh` ones are
//! in `msh_binary.rs`.

use std::path::Path;
use std::time::{Duration, Instant};

use bs_mesh::io::{Location, ParseError, inp, msh, obj, off, stl, vtk, vtu};

/// Runs `read`, which must fail within a second with a message holding every needle.
fn refused<T: std::fmt::Debug>(
    read: impl FnOnce() -> Result<T, ParseError>,
    needles: &[&str],
) -> ParseError {
    let start = Instant::now();
    let e = read().expect_err("a hostile count must be refused");
    assert!(start.elapsed() < Duration::from_secs(1), "took {:?}", start.elapsed());
    for n in needles {
        assert!(e.to_string().contains(n), "'{n}' not in: {e}");
    }
    e
}

#[test]
fn stl_binary_triangle_count() {
    let mut b = vec![0u8; 84 + 50];
    b[80..84].copy_from_slice(&2_000_000_000u32.to_le_bytes());
    let e = refused(|| stl::read(&b, Path::new("h.stl")), &["expected 2000000000 triangles"]);
    assert_eq!(e.location, Location::Byte(80));
}

#[test]
fn off_vertex_and_face_counts() {
    let p = Path::new("h.off");
    // OFF reserves at most what the file can hold and fails where the data ends, naming the
    // count.
    for (text, what, line) in [
        ("OFF\n2000000000 1 0\n0 0 0\n", "vertex 1 of 2000000000", 3),
        ("OFF\n3 2000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "face 1 of 2000000000", 6),
    ] {
        let e = refused(|| off::read(text.as_bytes(), p), &["unexpected end of file", what]);
        assert_eq!(e.location, Location::Line(line));
    }
}

#[test]
fn obj_has_no_counts_but_a_huge_index_is_an_error() {
    // OBJ declares no counts; the nearest hostile input is an index far past the vertices.
    let text = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2000000000\n";
    let e = refused(|| obj::read(text, Path::new("h.obj")), &["2000000000", "3 vertices"]);
    assert_eq!(e.location, Location::Line(4));
}

const MSH22: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n\
                     3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n";
const MSH41: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n\
                     0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n$Elements\n1 1 1 1\n3 1 4 1\n\
                     1 1 2 3 4\n$EndElements\n";

#[test]
fn msh_ascii_counts() {
    let p = Path::new("h.msh");
    assert_eq!(msh::read(MSH22.as_bytes(), p).unwrap().elements.len(), 1);
    assert_eq!(msh::read(MSH41.as_bytes(), p).unwrap().elements.len(), 1);
    for (base, from, to, line, what) in [
        (MSH22, "$Nodes\n4\n", "$Nodes\n2000000000\n", 5, "2000000000 nodes"),
        (MSH22, "$Elements\n1\n", "$Elements\n2000000000\n", 12, "2000000000 elements"),
        (MSH41, "$Nodes\n1 4 1 4\n", "$Nodes\n1 2000000000 1 4\n", 5, "2000000000 nodes"),
        (MSH41, "$Nodes\n1 4 1 4\n", "$Nodes\n2000000000 4 1 4\n", 5, "2000000000 node entity"),
        (MSH41, "3 1 0 4\n", "3 1 0 2000000000\n", 6, "2000000000 nodes in the block"),
        (MSH41, "$Elements\n1 1 1 1\n", "$Elements\n1 2000000000 1 1\n", 17, "2000000000 elements"),
        (MSH41, "3 1 4 1\n", "3 1 4 2000000000\n", 18, "2000000000 elements in the block"),
    ] {
        let text = base.replacen(from, to, 1);
        let e = refused(|| msh::read(text.as_bytes(), p), &[what, "corrupt"]);
        assert_eq!(e.location, Location::Line(line), "{e}");
    }
}

const VTK: &str = "# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\n\
                   POINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\n\
                   CELL_TYPES 1\n10\n";

#[test]
fn vtk_ascii_and_binary_counts() {
    let p = Path::new("h.vtk");
    assert_eq!(vtk::read(VTK.as_bytes(), p).unwrap().0.elements.len(), 1);
    for (from, to, line) in [
        ("POINTS 4 double", "POINTS 2000000000 double", 5),
        ("CELLS 1 5", "CELLS 1 2000000000", 7),
        ("CELL_TYPES 1", "CELL_TYPES 2000000000", 9),
    ] {
        let text = VTK.replacen(from, to, 1);
        let e = refused(|| vtk::read(text.as_bytes(), p), &["unexpected end of file", "corrupt"]);
        assert_eq!(e.location, Location::Line(line), "{e}");
    }
    let binary = "# vtk DataFile Version 4.2\nx\nBINARY\nDATASET UNSTRUCTURED_GRID\n\
                  POINTS 2000000000 double\n\0\0\0\0\0\0\0\0\n";
    refused(|| vtk::read(binary.as_bytes(), p), &["6000000000 binary double values", "remain"]);
}

const VTU: &str = "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" \
    byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n\
    <Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\
    0 0 0 1 0 0 0 1 0 0 0 1</DataArray>\n</Points>\n<Cells>\n\
    <DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 3</DataArray>\n\
    <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n\
    <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray>\n</Cells>\n\
    </Piece>\n</UnstructuredGrid>\n</VTKFile>\n";

#[test]
fn vtu_counts_and_block_sizes() {
    let p = Path::new("h.vtu");
    assert_eq!(vtu::read(VTU.as_bytes(), p).unwrap().0.elements.len(), 1);
    let text = VTU.replacen("NumberOfPoints=\"4\"", "NumberOfPoints=\"2000000000\"", 1);
    refused(|| vtu::read(text.as_bytes(), p), &["expected 2000000000 points"]);
    let text = VTU.replacen("NumberOfCells=\"1\"", "NumberOfCells=\"2000000000\"", 1);
    refused(|| vtu::read(text.as_bytes(), p), &["NumberOfCells is 2000000000"]);
    // A raw appended block whose header claims 2·10⁹ bytes.
    let mut b = VTU
        .replacen("format=\"ascii\">0 1 2 3</DataArray>", "format=\"appended\" offset=\"0\"/>", 1)
        .replacen("</VTKFile>\n", "<AppendedData encoding=\"raw\">\n_", 1)
        .into_bytes();
    b.extend_from_slice(&2_000_000_000u32.to_le_bytes());
    b.extend_from_slice(&[0u8; 16]);
    b.extend_from_slice(b"\n</AppendedData>\n</VTKFile>\n");
    refused(|| vtu::read(&b, p), &["2000000000 bytes"]);
}

#[test]
fn inp_generate_range_is_bounded_by_the_nodes() {
    // Abaqus decks declare no counts; the one range is GENERATE, which must only visit ids
    // that exist (here 4 of 4·10⁹).
    let deck = "*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n3, 0, 1, 0\n4, 0, 0, 1\n*ELEMENT, TYPE=C3D4\n\
                1, 1, 2, 3, 4\n*NSET, NSET=ALL, GENERATE\n1, 4000000000, 1\n";
    let start = Instant::now();
    let m = inp::read(deck.as_bytes(), Path::new("h.inp")).unwrap();
    assert!(start.elapsed() < Duration::from_secs(1));
    assert_eq!(m.node_set("ALL").unwrap(), [0, 1, 2, 3]);
}
