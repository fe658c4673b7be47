//! Binary gmsh `.msh` (4.1 and 2.2) against the ASCII reader: the binary files in
//! `fixtures/readers` were written by meshio from the gmsh-written ASCII cubes in
//! `fixtures/basic` (see `fixtures/readers/make.py`), so both readers must build the same
//! nodes, elements and sets. Plus hand-made corruptions: never a panic, always an error
//! naming a byte offset.

use std::path::{Path, PathBuf};

use bs_mesh::Mesh;
use bs_mesh::io::{Location, msh};
use proptest::prelude::*;

fn fixture_path(dir: &str, name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures").join(dir).join(name)
}

fn read(dir: &str, name: &str) -> Mesh {
    let path = fixture_path(dir, name);
    let bytes = std::fs::read(&path).expect("fixture readable");
    msh::read(&bytes, &path).unwrap_or_else(|e| panic!("{e}"))
}

fn check_same_as_ascii(stem: &str) {
    let ascii = read("basic", &format!("{stem}.msh"));
    for v in ["bin41", "bin22"] {
        let bin = read("readers", &format!("{stem}-{v}.msh"));
        assert_eq!(bin.node_ids, ascii.node_ids, "{stem}-{v}");
        // The binary files hold the same doubles the ASCII file printed: bitwise equal.
        assert_eq!(bin.nodes, ascii.nodes, "{stem}-{v}");
        assert_eq!(bin.element_ids, ascii.element_ids, "{stem}-{v}");
        assert_eq!(bin.elements, ascii.elements, "{stem}-{v}");
        assert_eq!(bin.node_sets, ascii.node_sets, "{stem}-{v}");
        assert_eq!(bin.element_sets, ascii.element_sets, "{stem}-{v}");
        assert_eq!(bin, ascii, "{stem}-{v}");
    }
}

#[test]
fn binary_tet_cube_equals_ascii() {
    check_same_as_ascii("cube-t4");
    let m = read("readers", "cube-t4-bin41.msh");
    assert_eq!((m.nodes.len(), m.elements.len()), (341, 1140));
    assert_eq!(m.element_set("CUBE").unwrap().len(), 1140);
}

#[test]
fn binary_hex_cube_equals_ascii() {
    check_same_as_ascii("cube-h8");
    let m = read("readers", "cube-h8-bin22.msh");
    assert_eq!((m.nodes.len(), m.elements.len()), (64, 27));
    assert_eq!(m.node_set("XMIN").unwrap().len(), 16);
}

/// A tiny binary 2.2 writer (test side, independent of the reader) so that the byte order
/// and corruptions can be chosen: one tet in physical group 7, one triangle in group 3.
fn tiny_v22(big_endian: bool) -> Vec<u8> {
    let int = |v: i32| if big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
    let dbl = |v: f64| if big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
    let mut b = b"$MeshFormat\n2.2 1 8\n".to_vec();
    b.extend(int(1));
    b.extend(b"\n$EndMeshFormat\n$PhysicalNames\n1\n3 7 \"brain\"\n$EndPhysicalNames\n$Nodes\n4\n");
    for (id, p) in
        [(10, [0.0, 0.0, 0.0]), (20, [1.0, 0.0, 0.0]), (30, [0.0, 1.0, 0.0]), (40, [0.0, 0.0, 1.0])]
    {
        b.extend(int(id));
        p.iter().for_each(|&x| b.extend(dbl(x)));
    }
    b.extend(b"\n$EndNodes\n$Elements\n2\n");
    // type 4 (tet), 1 element, 2 tags: id 5, physical 7, elementary 1, nodes.
    for v in [4, 1, 2, 5, 7, 1, 10, 20, 30, 40] {
        b.extend(int(v));
    }
    // type 2 (triangle), 1 element, 2 tags: id 6, physical 3, elementary 2, nodes.
    for v in [2, 1, 2, 6, 3, 2, 10, 20, 30] {
        b.extend(int(v));
    }
    b.extend(b"\n$EndElements\n");
    b
}

const TINY_ASCII: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 7 \"brain\"\n\
    $EndPhysicalNames\n$Nodes\n4\n10 0 0 0\n20 1 0 0\n30 0 1 0\n40 0 0 1\n$EndNodes\n$Elements\n2\n\
    5 4 2 7 1 10 20 30 40\n6 2 2 3 2 10 20 30\n$EndElements\n";

#[test]
fn both_byte_orders_equal_ascii() {
    let p = Path::new("tiny.msh");
    let ascii = msh::read(TINY_ASCII.as_bytes(), p).unwrap();
    assert_eq!(ascii.element_set("brain").unwrap(), [0]);
    assert_eq!(ascii.node_set("PHYSICAL_2D_3").unwrap(), [0, 1, 2]);
    for big in [false, true] {
        assert_eq!(msh::read(&tiny_v22(big), p).unwrap(), ascii, "big endian: {big}");
    }
}

fn at_byte(r: Result<Mesh, bs_mesh::io::ParseError>, needles: &[&str]) -> usize {
    let e = r.expect_err("an error");
    for n in needles {
        assert!(e.to_string().contains(n), "'{n}' not in: {e}");
    }
    match e.location {
        Location::Byte(b) => b,
        other => panic!("expected a byte offset, got {other:?}: {e}"),
    }
}

#[test]
fn binary_errors_name_the_byte_and_problem() {
    let p = Path::new("tiny.msh");
    let good = tiny_v22(false);
    // An unknown node in the tet: the error points at the element.
    let nodes_end = find(&good, b"$Elements\n2\n") + 12;
    let mut bad = good.clone();
    bad[nodes_end + 6 * 4..nodes_end + 7 * 4].copy_from_slice(&99i32.to_le_bytes());
    assert_eq!(at_byte(msh::read(&bad, p), &["element 5", "node 99"]), nodes_end + 12);
    // Second-order tets are refused with the fix.
    let mut bad = good.clone();
    bad[nodes_end..nodes_end + 4].copy_from_slice(&11i32.to_le_bytes());
    at_byte(msh::read(&bad, p), &["type 11", "-order 1"]);
    // A wrong byte-order int.
    let mut bad = good.clone();
    bad[20] = 7;
    assert_eq!(at_byte(msh::read(&bad, p), &["integer 1"]), 20);
    // Truncated inside the node data.
    let cut = find(&good, b"$Nodes\n4\n") + 9 + 30;
    at_byte(msh::read(&good[..cut], p), &["truncated"]);
}

fn find(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len()).position(|w| w == needle).expect("needle present")
}

/// Counts that the file cannot hold are refused before any allocation.
#[test]
fn hostile_counts_are_clear_errors() {
    let p = Path::new("hostile.msh");
    // 2.2: the counts are text lines.
    let good = tiny_v22(false);
    for (from, to, what) in [
        (&b"$Nodes\n4\n"[..], &b"$Nodes\n2000000000\n"[..], "2000000000 nodes"),
        (b"$Elements\n2\n", b"$Elements\n2000000000\n", "2000000000 elements"),
        (b"$PhysicalNames\n1\n", b"$PhysicalNames\n2000000000\n", "2000000000 physical names"),
    ] {
        let i = find(&good, from);
        let bad = [&good[..i], to, &good[i + from.len()..]].concat();
        at_byte(msh::read(&bad, p), &[what, "remain"]);
    }
    // 4.1: size_t counts right after "$Nodes\n" and "$Elements\n" (and the entity counts).
    let path = fixture_path("readers", "cube-t4-bin41.msh");
    let good = std::fs::read(&path).unwrap();
    for (section, field, what) in [
        (&b"$Nodes\n"[..], 1, "2000000000 nodes"),
        (b"$Nodes\n", 0, "2000000000 node entity blocks"),
        (b"$Elements\n", 1, "2000000000 elements"),
        (b"$Entities\n", 2, "2000000000 entities"),
    ] {
        let at = find(&good, section) + section.len() + 8 * field;
        let mut bad = good.clone();
        bad[at..at + 8].copy_from_slice(&2_000_000_000u64.to_le_bytes());
        at_byte(msh::read(&bad, &path), &[what, "remain"]);
    }
    // A block count in the node data.
    let at = find(&good, b"$Nodes\n") + 7 + 32 + 12;
    let mut bad = good.clone();
    bad[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    at_byte(msh::read(&bad, &path), &["nodes in the block", "remain"]);
}

const BINARY: [(&str, &str); 4] = [
    ("readers", "cube-t4-bin41.msh"),
    ("readers", "cube-t4-bin22.msh"),
    ("readers", "cube-h8-bin41.msh"),
    ("readers", "cube-h8-bin22.msh"),
];

proptest! {
    #[test]
    fn truncated_binary_never_panics(f in 0..BINARY.len(), cut in any::<usize>()) {
        let (dir, name) = BINARY[f];
        let bytes = std::fs::read(fixture_path(dir, name)).unwrap();
        let cut = cut % (bytes.len() + 1);
        let _ = msh::read(&bytes[..cut], Path::new(name));
    }

    #[test]
    fn mutated_binary_never_panics(
        f in 0..BINARY.len(),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 1..8),
    ) {
        let (dir, name) = BINARY[f];
        let mut bytes = std::fs::read(fixture_path(dir, name)).unwrap();
        let n = bytes.len();
        for (at, b) in flips {
            bytes[at % n] = b;
        }
        if let Ok(m) = msh::read(&bytes, Path::new(name)) {
            prop_assert_eq!(m.node_ids.len(), m.nodes.len());
            for e in &m.elements {
                prop_assert!(e.nodes().iter().all(|&i| i < m.nodes.len()));
            }
        }
    }
}
