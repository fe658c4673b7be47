//! Reader/writer tests for VTK legacy, VTU, STL, OBJ and OFF against the committed fixtures
//! (gmsh 4.15.2 / meshio 5.3.5, see fixtures/basic/README.md), round-trip properties of every
//! writer, robustness of every reader against truncated and mutated files, and the wording and
//! location of errors.

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use bs_mesh::io::{Field, Fields, Location, ParseError, obj, off, stl, vtk, vtu};
use bs_mesh::{Element, Mesh, Point3, TriSurface};
use proptest::prelude::*;

fn fixture(name: &str) -> (Vec<u8>, PathBuf) {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/basic").join(name);
    (std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())), p)
}

fn read_vtu(name: &str) -> (Mesh, Fields) {
    let (b, p) = fixture(name);
    vtu::read(&b, &p).unwrap_or_else(|e| panic!("{e}"))
}

fn read_vtk(name: &str) -> (Mesh, Fields) {
    let (b, p) = fixture(name);
    vtk::read(&b, &p).unwrap_or_else(|e| panic!("{e}"))
}

fn read_surface(name: &str) -> TriSurface {
    let (b, p) = fixture(name);
    let r = match name.rsplit('.').next() {
        Some("stl") => stl::read(&b, &p),
        Some("obj") => obj::read(&b, &p),
        _ => off::read(&b, &p),
    };
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// Enclosed volume by the divergence theorem: sum of a·(b×c)/6 over the triangles.
fn enclosed_volume(s: &TriSurface) -> f64 {
    s.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| s.vertices[i].coords);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum()
}

// ----------------------------------------------------------------------------------------
// Real fixtures
// ----------------------------------------------------------------------------------------

#[test]
fn sphere_vtu_and_vtk_hold_the_same_ball() {
    let (a, fa) = read_vtu("sphere.vtu"); // meshio binary, zlib-compressed
    let (b, fb) = read_vtk("sphere.vtk"); // meshio ASCII, VTK 5.1 OFFSETS/CONNECTIVITY
    // meshio reports 259 points and 898 tetrahedra for both files.
    assert_eq!(a.nodes.len(), 259);
    assert_eq!(a.elements.len(), 898);
    assert_eq!(b.nodes.len(), 259);
    // meshio prints shortest round-trip decimals, so the ASCII coordinates equal the binary
    // ones bitwise (numpy.array_equal on meshio's own reads of the two files is True).
    assert_eq!(a.nodes, b.nodes);
    assert_eq!(a.elements, b.elements);
    // No id arrays in meshio files: ids are 0-based positions (VTK convention).
    assert_eq!(a.node_ids, (0..259).collect::<Vec<u64>>());
    assert_eq!(b.element_ids, (0..898).collect::<Vec<u64>>());
    assert!(fa.point.is_empty() && fa.cell.is_empty() && fb.point.is_empty());
}

#[test]
fn sphere_volume_is_a_ball_of_radius_10() {
    for (m, _) in [read_vtu("sphere.vtu"), read_vtk("sphere.vtk")] {
        let vols: Vec<f64> = (0..m.elements.len()).map(|e| m.element_volume(e)).collect();
        assert!(vols.iter().all(|&v| v > 0.0), "every gmsh tetrahedron is positively oriented");
        let total: f64 = vols.iter().sum();
        // numpy on meshio's read of sphere.vtu (sum of (b-a)·((c-a)×(d-a))/6) gives
        // 4066.7268314196917; summation order differs, so allow 1e-12 relative.
        approx::assert_relative_eq!(total, 4066.7268314196917, max_relative = 1e-12);
        // An inscribed polyhedral ball (mesh size 3, radius 10) loses volume to chordal
        // error: 2.9% here, within the 3% bound.
        let exact = 4.0 / 3.0 * PI * 1000.0;
        assert!(total < exact && (exact - total) / exact < 0.03, "volume {total} vs {exact}");
    }
}

#[test]
fn all_shell_files_hold_the_same_closed_sphere() {
    let names = ["shell.stl", "shell-ascii.stl", "shell-gmsh.stl", "shell.obj", "shell.off"];
    let exact = 4.0 / 3.0 * PI * 12f64.powi(3);
    let reference = read_surface("shell.off");
    // The OFF header says 161 vertices and 318 triangles; a closed genus-0 surface has
    // V - E + F = 2 with E = 3F/2: 161 - 477 + 318 = 2.
    assert_eq!((reference.vertices.len(), reference.triangles.len()), (161, 318));
    for name in names {
        let s = read_surface(name);
        assert_eq!(s.vertices.len(), 161, "{name}: vertices after merging");
        assert_eq!(s.triangles.len(), 318, "{name}");
        let v = enclosed_volume(&s);
        // numpy on meshio's reads of shell.off/obj/ascii.stl gives 6985.00361617477 (and
        // 6985.004 in f32 for shell.stl, whose coordinates are f32: relative error ≤ 3·2^-24
        // per product, so 1e-6 bounds it).
        approx::assert_relative_eq!(v.abs(), 6985.00361617477, max_relative = 1e-6);
        // The surface is an inscribed polyhedron with mesh size 4 on radius 12: its volume is
        // 3.5% below the ball's (chordal error), so the bound against the closed form is 4%.
        let rel = (exact - v.abs()) / exact;
        assert!(rel > 0.0 && rel < 0.04, "{name}: volume {v} vs {exact}");
        if name != "shell-gmsh.stl" {
            assert!(v > 0.0, "{name}: meshio files are oriented outward");
        }
        // Every file holds the same points: binary STL rounds to f32 (|x| ≤ 12, so the error
        // is ≤ 12·2^-24 ≈ 7.2e-7); ASCII files print 12+ significant digits (error ≤ 1e-10).
        let tol = if name == "shell.stl" { 7.2e-7 } else { 1e-10 };
        for p in &s.vertices {
            let d = reference.vertices.iter().map(|q| (p - q).amax()).fold(f64::INFINITY, f64::min);
            assert!(d <= tol, "{name}: vertex {p} is {d} from every OFF vertex");
        }
    }
    // OBJ and OFF are written from the same merged arrays: identical in order.
    assert_eq!(read_surface("shell.obj"), reference);
}

// ----------------------------------------------------------------------------------------
// Round trips
// ----------------------------------------------------------------------------------------

fn coord() -> impl Strategy<Value = f64> {
    // Normal and subnormal values of both signs and zero: magnitudes from 4.9e-324 to 1.8e308.
    use proptest::num::f64::{NEGATIVE, NORMAL, POSITIVE, SUBNORMAL, ZERO};
    prop_oneof![POSITIVE | NEGATIVE | NORMAL | SUBNORMAL | ZERO, -1e3..1e3f64,]
}

fn name() -> impl Strategy<Value = String> {
    "[A-Za-z][A-Za-z0-9 _&<>%\"']{0,6}"
        .prop_filter("reserved", |s| s != "node_id" && s != "element_id")
}

fn mesh_and_fields() -> impl Strategy<Value = (Mesh, Fields)> {
    (8usize..14, 0usize..6).prop_flat_map(|(nn, ne)| {
        let nodes = prop::collection::vec([coord(), coord(), coord()], nn);
        let elements = prop::collection::vec((any::<bool>(), prop::collection::vec(0..nn, 8)), ne);
        let node_ids = prop::collection::vec(any::<u64>(), nn);
        let element_ids = prop::collection::vec(any::<u64>(), ne);
        let nsets =
            prop::collection::btree_map(name(), prop::collection::vec(any::<bool>(), nn), 0..3);
        let esets =
            prop::collection::btree_map(name(), prop::collection::vec(any::<bool>(), ne), 0..3);
        let pfields = prop::collection::vec(
            (name(), 1usize..4).prop_flat_map(move |(n, c)| {
                prop::collection::vec(coord(), c * nn)
                    .prop_map(move |v| Field::new(n.clone(), c, v))
            }),
            0..3,
        );
        let cfields = prop::collection::vec(
            (name(), 1usize..4).prop_flat_map(move |(n, c)| {
                prop::collection::vec(coord(), c * ne)
                    .prop_map(move |v| Field::new(n.clone(), c, v))
            }),
            0..3,
        );
        (nodes, elements, node_ids, element_ids, nsets, esets, pfields, cfields).prop_map(
            |(nodes, elements, node_ids, element_ids, nsets, esets, point, cell)| {
                let members = |m: BTreeMap<String, Vec<bool>>| {
                    m.into_iter()
                        .map(|(k, v)| {
                            (k, v.iter().enumerate().filter(|x| *x.1).map(|x| x.0).collect())
                        })
                        .collect()
                };
                let mesh = Mesh {
                    nodes: nodes.into_iter().map(|c| Point3::new(c[0], c[1], c[2])).collect(),
                    node_ids,
                    elements: elements
                        .into_iter()
                        .map(|(tet, n)| {
                            Element::from_nodes(if tet { &n[..4] } else { &n[..] }).unwrap()
                        })
                        .collect(),
                    element_ids,
                    node_sets: members(nsets),
                    element_sets: members(esets),
                };
                (mesh, Fields { point, cell, ..Default::default() })
            },
        )
    })
}

fn surface() -> impl Strategy<Value = TriSurface> {
    (3usize..12, 0usize..10).prop_flat_map(|(nv, nt)| {
        (
            prop::collection::vec([coord(), coord(), coord()], nv),
            prop::collection::vec([0..nv, 0..nv, 0..nv], nt),
        )
            .prop_map(|(v, t)| TriSurface {
                vertices: v.into_iter().map(|c| Point3::new(c[0], c[1], c[2])).collect(),
                triangles: t,
            })
    })
}

/// What an STL reader must return: the triangle soup with vertices mapped through `round`,
/// merged by exact equality (brute force, in order of first appearance).
fn expected_stl(s: &TriSurface, round: impl Fn(f64) -> f64) -> TriSurface {
    let mut out = TriSurface::default();
    for t in &s.triangles {
        let tri = t.map(|i| {
            let p = s.vertices[i].map(&round);
            match out.vertices.iter().position(|q| *q == p) {
                Some(k) => k,
                None => {
                    out.vertices.push(p);
                    out.vertices.len() - 1
                }
            }
        });
        out.triangles.push(tri);
    }
    out
}

fn p(name: &str) -> PathBuf {
    PathBuf::from(name)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn vtu_round_trip_is_exact((mesh, fields) in mesh_and_fields()) {
        for enc in [vtu::Encoding::Inline, vtu::Encoding::Appended] {
            let mut b = Vec::new();
            vtu::write(&mut b, &mesh, &fields, enc).unwrap();
            let (m, f) = vtu::read(&b, &p("r.vtu")).unwrap();
            // Point3 equality is f64 equality; coordinates are never NaN here, and signed
            // zeros are checked bitwise below.
            prop_assert_eq!(&m, &mesh);
            prop_assert_eq!(&f, &fields);
            for (a, b) in m.nodes.iter().zip(&mesh.nodes) {
                prop_assert!(a.iter().zip(b.iter()).all(|(x, y)| x.to_bits() == y.to_bits()));
            }
        }
    }

    #[test]
    fn vtk_round_trip_is_exact((mesh, fields) in mesh_and_fields()) {
        let mut b = Vec::new();
        vtk::write(&mut b, &mesh, &fields).unwrap();
        let (m, f) = vtk::read(&b, &p("r.vtk")).unwrap();
        prop_assert_eq!(&m, &mesh);
        prop_assert_eq!(&f, &fields);
        for (a, b) in m.nodes.iter().zip(&mesh.nodes) {
            prop_assert!(a.iter().zip(b.iter()).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }

    #[test]
    fn stl_round_trips_up_to_f32(s in surface()) {
        let mut b = Vec::new();
        let w = stl::write_binary(&mut b, &s);
        // Binary STL holds f32: the result is exactly the f32-rounded soup, merged.
        let want = expected_stl(&s, |x| x as f32 as f64);
        if want.vertices.iter().all(|v| v.iter().all(|c| c.is_finite())) {
            w.unwrap();
            prop_assert_eq!(b.len(), 84 + 50 * s.triangles.len());
            prop_assert_eq!(stl::read(&b, &p("r.stl")).unwrap(), want);
        } else {
            // Values beyond the f32 range would become infinite: the writer refuses.
            let e = w.unwrap_err();
            prop_assert!(e.to_string().contains("beyond the f32 range"), "{e}");
        }
        let mut a = Vec::new();
        stl::write_ascii(&mut a, &s).unwrap();
        prop_assert_eq!(stl::read(&a, &p("r.stl")).unwrap(), expected_stl(&s, |x| x + 0.0));
    }

    #[test]
    fn obj_and_off_round_trip_exactly(s in surface()) {
        let mut b = Vec::new();
        obj::write(&mut b, &s).unwrap();
        prop_assert_eq!(obj::read(&b, &p("r.obj")).unwrap(), s.clone());
        let mut b = Vec::new();
        off::write(&mut b, &s).unwrap();
        prop_assert_eq!(off::read(&b, &p("r.off")).unwrap(), s);
    }
}

// ----------------------------------------------------------------------------------------
// Robustness: truncated and mutated files never panic
// ----------------------------------------------------------------------------------------

type Reader = fn(&[u8], &Path) -> Result<(), ParseError>;

fn readers() -> Vec<(&'static str, Vec<u8>, Reader)> {
    let vol_vtu: Reader = |b, p| vtu::read(b, p).map(drop);
    let vol_vtk: Reader = |b, p| vtk::read(b, p).map(drop);
    let s_stl: Reader = |b, p| stl::read(b, p).map(drop);
    let s_obj: Reader = |b, p| obj::read(b, p).map(drop);
    let s_off: Reader = |b, p| off::read(b, p).map(drop);
    let (ball, fields) = read_vtu("sphere.vtu");
    let mut ball = ball;
    ball.node_sets.insert("TOP".into(), vec![0, 5, 9]);
    ball.element_sets.insert("SOME".into(), vec![1, 2]);
    let mut inline = Vec::new();
    vtu::write(&mut inline, &ball, &fields, vtu::Encoding::Inline).unwrap();
    let mut appended = Vec::new();
    vtu::write(&mut appended, &ball, &fields, vtu::Encoding::Appended).unwrap();
    let mut legacy = Vec::new();
    vtk::write(&mut legacy, &ball, &fields).unwrap();
    let mut out = vec![
        ("inline.vtu", inline, vol_vtu),
        ("appended.vtu", appended, vol_vtu),
        ("written.vtk", legacy, vol_vtk),
        ("binary.vtk", binary_vtk(true), vol_vtk),
    ];
    for (n, r) in [
        ("sphere.vtu", vol_vtu),
        ("sphere.vtk", vol_vtk),
        ("shell.stl", s_stl),
        ("shell-ascii.stl", s_stl),
        ("shell-gmsh.stl", s_stl),
        ("shell.obj", s_obj),
        ("shell.off", s_off),
    ] {
        out.push((n, fixture(n).0, r));
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn truncated_files_never_panic(cut in 0.0..1.0f64) {
        for (name, bytes, read) in readers() {
            let n = (cut * bytes.len() as f64) as usize;
            let _ = read(&bytes[..n], &p(name));
        }
    }

    #[test]
    fn mutated_files_never_panic(edits in prop::collection::vec((0.0..1.0f64, any::<u8>()), 1..8)) {
        for (name, mut bytes, read) in readers() {
            let len = bytes.len();
            for &(at, b) in &edits {
                bytes[((at * len as f64) as usize).min(len - 1)] = b;
            }
            let _ = read(&bytes, &p(name));
        }
    }

    #[test]
    fn mutated_digits_never_panic(edits in prop::collection::vec((0.0..1.0f64, 0u8..10), 1..8)) {
        // Replacing digits by digits keeps files well-formed but corrupts counts, sizes and
        // offsets, which must not cause huge allocations or out-of-range indexing.
        for (name, mut bytes, read) in readers() {
            let digits: Vec<usize> = (0..bytes.len()).filter(|&i| bytes[i].is_ascii_digit()).collect();
            if digits.is_empty() { continue; }
            for &(at, d) in &edits {
                bytes[digits[((at * digits.len() as f64) as usize).min(digits.len() - 1)]] = b'0' + d;
            }
            let _ = read(&bytes, &p(name));
        }
    }
}

// ----------------------------------------------------------------------------------------
// Hand-made files: binary legacy VTK, raw appended VTU, ASCII VTU, errors
// ----------------------------------------------------------------------------------------

/// A big-endian BINARY legacy VTK file with one tetrahedron and one triangle (skipped), a
/// scalar point field and a node_id array; VTK 5.1 layout when `v51`, classic otherwise.
fn binary_vtk(v51: bool) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(
        b"# vtk DataFile Version 5.1\nhand made\nBINARY\nDATASET UNSTRUCTURED_GRID\n",
    );
    b.extend_from_slice(b"POINTS 4 float\n");
    for x in [0f32, 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.5] {
        b.extend_from_slice(&x.to_be_bytes());
    }
    if v51 {
        b.extend_from_slice(b"\nCELLS 3 7\nOFFSETS vtktypeint64\n");
        for o in [0i64, 4, 7] {
            b.extend_from_slice(&o.to_be_bytes());
        }
        b.extend_from_slice(b"\nCONNECTIVITY vtktypeint64\n");
        for c in [0i64, 1, 2, 3, 0, 1, 2] {
            b.extend_from_slice(&c.to_be_bytes());
        }
    } else {
        b.extend_from_slice(b"\nCELLS 2 9\n");
        for c in [4i32, 0, 1, 2, 3, 3, 0, 1, 2] {
            b.extend_from_slice(&c.to_be_bytes());
        }
    }
    b.extend_from_slice(b"\nCELL_TYPES 2\n");
    for t in [10i32, 5] {
        b.extend_from_slice(&t.to_be_bytes());
    }
    b.extend_from_slice(b"\nPOINT_DATA 4\nSCALARS temperature double 1\nLOOKUP_TABLE default\n");
    for x in [36.5f64, -1.0, 1e-300, 2.0] {
        b.extend_from_slice(&x.to_be_bytes());
    }
    b.extend_from_slice(b"\nFIELD FieldData 1\nnode_id 1 4 long\n");
    for i in [10i64, 20, 30, -1] {
        b.extend_from_slice(&i.to_be_bytes());
    }
    b.extend_from_slice(b"\nCELL_DATA 2\nVECTORS v float\n");
    for x in [1f32, 2., 3., 4., 5., 6.] {
        b.extend_from_slice(&x.to_be_bytes());
    }
    b.push(b'\n');
    b
}

#[test]
fn binary_legacy_vtk_both_cell_layouts() {
    for v51 in [true, false] {
        let (m, f) = vtk::read(&binary_vtk(v51), &p("b.vtk")).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.nodes[3], Point3::new(0.0, 0.0, 1.5));
        assert_eq!(m.elements, vec![Element::tet4([0, 1, 2, 3])]);
        assert_eq!(m.element_ids, vec![0], "the triangle (cell 1) is skipped");
        assert_eq!(m.node_ids, vec![10, 20, 30, u64::MAX]);
        assert_eq!(f.point, vec![Field::new("temperature", 1, vec![36.5, -1.0, 1e-300, 2.0])]);
        assert_eq!(f.cell, vec![Field::new("v", 3, vec![1.0, 2.0, 3.0])]);
        approx::assert_relative_eq!(m.element_volume(0), 1.5 / 6.0, epsilon = 1e-15);
    }
}

/// A VTU with UInt32 headers, raw appended data, an ASCII array and Float32/Int32 types.
fn raw_appended_vtu() -> Vec<u8> {
    let coords: Vec<u8> = [0f32, 0., 0., 2., 0., 0., 0., 2., 0., 0., 0., 2.]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let conn: Vec<u8> = [0i32, 1, 2, 3].iter().flat_map(|x| x.to_le_bytes()).collect();
    let mut data = Vec::new();
    let mut offsets = Vec::new();
    for block in [&coords, &conn] {
        offsets.push(data.len());
        data.extend_from_slice(&(block.len() as u32).to_le_bytes());
        data.extend_from_slice(block);
    }
    let mut f = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" \
         byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"4\" \
         NumberOfCells=\"1\">\n<PointData>\n<DataArray type=\"Int32\" Name=\"nset:A &amp; B\" \
         format=\"ascii\">0 1 1 0</DataArray>\n</PointData>\n<Points>\n<DataArray \
         type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{}\"/>\n\
         </Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" \
         format=\"appended\" offset=\"{}\"/>\n<DataArray type=\"Int32\" Name=\"offsets\" \
         format=\"ascii\">4</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" \
         format=\"ascii\">10</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n\
         <AppendedData encoding=\"raw\">\n_",
        offsets[0], offsets[1]
    )
    .into_bytes();
    f.extend_from_slice(&data);
    f.extend_from_slice(b"\n</AppendedData>\n</VTKFile>\n");
    f
}

#[test]
fn raw_appended_vtu_with_uint32_headers() {
    let (m, f) = vtu::read(&raw_appended_vtu(), &p("raw.vtu")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(m.nodes[1], Point3::new(2.0, 0.0, 0.0));
    assert_eq!(m.elements, vec![Element::tet4([0, 1, 2, 3])]);
    assert_eq!(m.node_set("A & B"), Some(&[1usize, 2][..]));
    approx::assert_relative_eq!(m.element_volume(0), 8.0 / 6.0, epsilon = 1e-15);
    assert!(f.point.is_empty());
    // Truncating the raw data is reported, not a panic.
    let b = raw_appended_vtu();
    for cut in (b.len() - 60..b.len()).step_by(7) {
        let _ = vtu::read(&b[..cut], &p("raw.vtu"));
    }
}

fn replace(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    let s = String::from_utf8_lossy(bytes).into_owned();
    assert!(s.contains(from), "{from}");
    s.replacen(from, to, 1).into_bytes()
}

#[test]
fn vtu_errors_name_the_problem() {
    let (sphere, path) = fixture("sphere.vtu");
    let lz4 = replace(&sphere, "vtkZLibDataCompressor", "vtkLZ4DataCompressor");
    let e = vtu::read(&lz4, &path).unwrap_err();
    assert!(e.message.contains("vtkLZ4DataCompressor is not supported"), "{}", e.message);
    assert_eq!(e.location, Location::Byte(22));

    // A quadratic tetrahedron: clear error with the cell index and the fix.
    let quad = replace(&raw_appended_vtu(), "format=\"ascii\">10<", "format=\"ascii\">24<");
    let e = vtu::read(&quad, &p("q.vtu")).unwrap_err();
    assert!(
        e.message.starts_with("cell 0 is a quadratic tetrahedron (VTK type 24)"),
        "{}",
        e.message
    );
    assert!(e.message.contains("-order 1"), "{}", e.message);

    let bad = replace(&raw_appended_vtu(), ">0 1 1 0<", ">0 1 x 0<");
    let e = vtu::read(&bad, &p("b.vtu")).unwrap_err();
    assert_eq!(e.message, "DataArray 'nset:A & B': expected an integer, found 'x'");

    let short = replace(&raw_appended_vtu(), ">0 1 1 0<", ">0 1 1<");
    let e = vtu::read(&short, &p("b.vtu")).unwrap_err();
    assert!(
        e.message.contains("'nset:A & B' has 3 values with 1 components; expected 4"),
        "{}",
        e.message
    );

    let e =
        vtu::read(b"<VTKFile type=\"PolyData\"><PolyData/></VTKFile>", &p("x.vtu")).unwrap_err();
    assert!(e.message.contains("type 'PolyData'"), "{}", e.message);
}

#[test]
fn vtk_errors_name_the_line() {
    let (b, path) = fixture("sphere.vtk");
    let e = vtk::read(&replace(&b, "CELL_TYPES 898\n10", "CELL_TYPES 898\n13"), &path).unwrap_err();
    assert!(e.message.starts_with("cell 0 is a wedge (VTK type 13)"), "{}", e.message);
    let e = vtk::read(&replace(&b, "POINTS 259 double", "POINTS 259 doubel"), &path).unwrap_err();
    assert_eq!(e.location, Location::Line(5));
    assert!(e.message.contains("data type 'doubel' is not supported"), "{}", e.message);
    let e = vtk::read(&replace(&b, "-1.499759782661858e-31", "-1.4997x"), &path).unwrap_err();
    assert_eq!(e.location, Location::Line(6));
    assert_eq!(e.message, "POINTS: expected a number, found '-1.4997x'");
    let e = vtk::read(&b[..200], &path).unwrap_err();
    assert!(e.message.starts_with("unexpected end of file: POINTS has"), "{}", e.message);
    let e =
        vtk::read(b"# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\n", &path).unwrap_err();
    assert_eq!(e.location, Location::Line(4));
    assert!(e.message.contains("dataset type POLYDATA"), "{}", e.message);
    // A binary file whose count promises more data than the file holds: byte offset, no
    // allocation of the promised size.
    let big = replace(&binary_vtk(true), "POINTS 4 float", "POINTS 400000000000 float");
    let e = vtk::read(&big, &path).unwrap_err();
    assert!(matches!(e.location, Location::Byte(_)), "{e}");
    assert!(e.message.contains("only"), "{}", e.message);
}

#[test]
fn writers_reject_inconsistent_input() {
    let mesh = Mesh::new(vec![Point3::origin(); 4], vec![Element::tet4([0, 1, 2, 3])]);
    let fields = Fields {
        point: vec![Field::new("u", 3, vec![0.0; 11])],
        cell: vec![],
        ..Default::default()
    };
    let e = vtu::write(&mut Vec::new(), &mesh, &fields, vtu::Encoding::Appended).unwrap_err();
    assert!(e.to_string().contains("point field 'u' has 11 values with 3 components"), "{e}");
    let fields = Fields {
        point: vec![Field::new("node_id", 1, vec![0.0; 4])],
        cell: vec![],
        ..Default::default()
    };
    assert!(vtk::write(&mut Vec::new(), &mesh, &fields).is_err());
    let bad = Mesh::new(vec![Point3::origin(); 3], vec![Element::tet4([0, 1, 2, 3])]);
    assert!(vtu::write(&mut Vec::new(), &bad, &Fields::default(), vtu::Encoding::Inline).is_err());
}

#[test]
fn extreme_counts_are_errors_not_overflows() {
    let e = obj::read(b"v 0 0 0\nf -9223372036854775808 1 1\n", &p("x.obj")).unwrap_err();
    assert_eq!(e.location, Location::Line(2));
    assert!(e.message.starts_with("relative vertex index -9223372036854775808"), "{}", e.message);
    let huge = replace(
        &raw_appended_vtu(),
        "Name=\"nset:A &amp; B\"",
        "Name=\"x\" NumberOfComponents=\"18446744073709551615\"",
    );
    let e = vtu::read(&huge, &p("x.vtu")).unwrap_err();
    assert!(
        e.message.contains("array 'x' has 4 values with 18446744073709551615 components"),
        "{}",
        e.message
    );
    let text = "# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 1 double\n0 0 0\n\
                CELLS 0 0\nCELL_TYPES 0\nPOINT_DATA 1\nFIELD f 1\nbig 18446744073709551615 0 double\n";
    let e = vtk::read(text.as_bytes(), &p("x.vtk")).unwrap_err();
    assert_eq!(e.location, Location::Line(11));
    assert!(e.message.contains("POINT_DATA array 'big' has 0 values"), "{}", e.message);
}

#[test]
fn vtu_field_data_strings_round_trip() {
    // The frame of a result travels as a FieldData String array named SPACE.
    let mesh = bs_mesh::structured::box_mesh(1, 1.0, true);
    let fields = Fields {
        field_data: vec![("SPACE".into(), "LPS".into()), ("NOTE".into(), "a <b> & c".into())],
        ..Default::default()
    };
    let mut bytes = Vec::new();
    bs_mesh::io::vtu::write(&mut bytes, &mesh, &fields, bs_mesh::io::vtu::Encoding::Appended)
        .unwrap();
    let text = String::from_utf8_lossy(&bytes);
    assert!(text.contains("<DataArray type=\"String\" Name=\"SPACE\""), "{text}");
    let (back, f) = bs_mesh::io::vtu::read(&bytes, Path::new("t.vtu")).unwrap();
    assert_eq!(back.nodes, mesh.nodes);
    assert_eq!(f.field_data, fields.field_data);
}
