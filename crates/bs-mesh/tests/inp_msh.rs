//! Abaqus `.inp` and Gmsh `.msh` readers (and the `.inp` writer) against the gmsh-written
//! fixtures in `fixtures/basic`, hand-written decks exercising the syntax, error messages,
//! robustness to corrupted input, and write→read round trips.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use bs_mesh::io::{Location, ParseError, inp, msh};
use bs_mesh::{Element, ElementKind, Mesh, Point3};
use proptest::prelude::*;

fn fixture_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/basic").join(name)
}

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(fixture_path(name)).expect("fixture readable")
}

fn read_fixture(name: &str) -> Mesh {
    let bytes = fixture(name);
    let path = fixture_path(name);
    let r =
        if name.ends_with(".inp") { inp::read(&bytes, &path) } else { msh::read(&bytes, &path) };
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn inp_str(text: &str) -> Result<Mesh, ParseError> {
    inp::read(text.as_bytes(), Path::new("test.inp"))
}

fn msh_str(text: &str) -> Result<Mesh, ParseError> {
    msh::read(text.as_bytes(), Path::new("test.msh"))
}

fn coords_by_id(m: &Mesh) -> BTreeMap<u64, [f64; 3]> {
    m.node_ids.iter().zip(&m.nodes).map(|(&id, p)| (id, [p.x, p.y, p.z])).collect()
}

/// Element connectivity by ids: element id → (kind, node ids).
fn elements_by_id(m: &Mesh) -> BTreeMap<u64, (ElementKind, Vec<u64>)> {
    m.element_ids
        .iter()
        .zip(&m.elements)
        .map(|(&id, e)| (id, (e.kind(), e.nodes().iter().map(|&n| m.node_ids[n]).collect())))
        .collect()
}

fn node_set_ids(m: &Mesh) -> BTreeMap<String, BTreeSet<u64>> {
    m.node_sets
        .iter()
        .map(|(k, v)| (k.clone(), v.iter().map(|&i| m.node_ids[i]).collect()))
        .collect()
}

fn total_volume(m: &Mesh) -> f64 {
    (0..m.elements.len()).map(|e| m.element_volume(e)).sum()
}

/// The three gmsh exports of one cube describe the same mesh.
fn check_cube_formats_agree(stem: &str, kind: ElementKind, elements: usize) {
    let v41 = read_fixture(&format!("{stem}.msh"));
    let v22 = read_fixture(&format!("{stem}-v22.msh"));
    let deck = read_fixture(&format!("{stem}.inp"));
    for m in [&v41, &v22, &deck] {
        assert_eq!(m.nodes.len(), v41.nodes.len());
        assert_eq!(m.elements.len(), elements);
        assert!(m.elements.iter().all(|e| e.kind() == kind));
        assert_eq!(elements_by_id(m), elements_by_id(&v41));
        assert_eq!(node_set_ids(m), node_set_ids(&v41));
    }
    // Both .msh versions print the same 16 significant digits: bitwise equal.
    assert_eq!(coords_by_id(&v22), coords_by_id(&v41));
    // gmsh's .inp writer prints 14 significant digits; coordinates are in [0, 1], so the two
    // roundings differ by less than 1e-13.
    let a = coords_by_id(&deck);
    let b = coords_by_id(&v41);
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (id, p) in &a {
        for k in 0..3 {
            assert!((p[k] - b[id][k]).abs() < 1e-13, "node {id}: {p:?} vs {:?}", b[id]);
        }
    }
    let names: Vec<&str> = v41.node_sets.keys().map(String::as_str).collect();
    assert_eq!(names, ["CUBE", "XMAX", "XMIN", "YMAX", "YMIN", "ZMAX", "ZMIN"]);
    // The 3D physical group CUBE is an element set holding every element; in the .inp the
    // surface sets XMIN… only listed skipped CPS elements and are dropped.
    for m in [&v41, &v22] {
        assert_eq!(m.element_sets.keys().collect::<Vec<_>>(), ["CUBE"]);
    }
    assert_eq!(deck.element_sets.keys().collect::<Vec<_>>(), ["CUBE", "Volume1"]);
    for m in [&v41, &v22, &deck] {
        assert_eq!(m.element_set("CUBE").unwrap(), (0..elements).collect::<Vec<_>>());
        assert_eq!(m.node_set("CUBE").unwrap().len(), m.nodes.len());
        for (set, axis, value) in [
            ("XMIN", 0, 0.0),
            ("XMAX", 0, 1.0),
            ("YMIN", 1, 0.0),
            ("YMAX", 1, 1.0),
            ("ZMIN", 2, 0.0),
            ("ZMAX", 2, 1.0),
        ] {
            let s = m.node_set(set).unwrap();
            assert!(!s.is_empty());
            // Exact: gmsh puts face nodes exactly on the face plane.
            assert!(s.iter().all(|&i| m.nodes[i][axis] == value), "{set}");
            // And every node on that plane is in the set.
            let on_plane = m.nodes.iter().filter(|p| p[axis] == value).count();
            assert_eq!(s.len(), on_plane, "{set}");
        }
        // Unit cube: the elements tile it, so the volumes add up to 1 (rounding only).
        assert!((total_volume(m) - 1.0).abs() < 1e-12, "volume {}", total_volume(m));
        assert!((0..m.elements.len()).all(|e| m.element_volume(e) > 0.0));
    }
}

#[test]
fn tet_cube_agrees_across_formats() {
    check_cube_formats_agree("cube-t4", ElementKind::Tet4, 1680 - 540);
}

#[test]
fn hex_cube_agrees_across_formats() {
    // 3×3×3 structured hexes, 4×4×4 nodes.
    check_cube_formats_agree("cube-h8", ElementKind::Hex8, 27);
    assert_eq!(read_fixture("cube-h8.msh").nodes.len(), 64);
}

#[test]
fn sphere_volume_close_to_ball() {
    let m = read_fixture("sphere.msh");
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 1000.0;
    let v = total_volume(&m);
    // The boundary nodes lie on the sphere r = 10 and the facets between them are flat, so
    // the tet mesh is an inscribed polyhedron: strictly smaller than the ball. With this
    // coarse mesh (898 tets) the missing caps are 2.9 % of the volume (measured 0.97086),
    // inside the 3 % the issue allows.
    assert!(v < exact, "{v} >= {exact}");
    assert!(v > 0.97 * exact, "{v} vs {exact}");
    assert!((0..m.elements.len()).all(|e| m.element_volume(e) > 0.0));
    assert!(m.nodes.iter().all(|p| p.coords.norm() <= 10.0 + 1e-9));
    assert_eq!(m.element_sets.keys().collect::<Vec<_>>(), ["BALL"]);
    // The surface group's nodes are all on the sphere.
    let surf = m.node_set("SURFACE").unwrap();
    assert!(!surf.is_empty());
    assert!(surf.iter().all(|&i| (m.nodes[i].coords.norm() - 10.0).abs() < 1e-9));
}

#[test]
fn inp_syntax_features() {
    let deck = "\
*Heading
 a test deck, with commas
** a comment
*node, nset=ALLN
 10 , 0 , 0 , 0
 30, 1.0, 0.0, 0.0
20,0,1,0
 40, 0, 0, 1D0
50, 1, 1, 1
*MATERIAL, NAME=brain
*ELASTIC
3000., 0.49
*Element, Type=c3d4, ELSET=Brain
 7, 10, 30,
 20, 40
 3, 30, 20, 40, 50
*ELEMENT, TYPE=S3R, ELSET=Skin
100, 10, 30, 20
*Nset, nset=Fixed
10,
20
*NSET, NSET=gen, GENERATE
10, 50, 20
*ELSET, ELSET=brain
3, 100,
*ELSET, ELSET=SkinOnly
100
*NSET, NSET=fromEl, ELSET=BRAIN
*NSET, NSET=merged
Fixed, 50
*STEP
*STATIC
*END STEP
";
    let m = inp_str(deck).unwrap();
    assert_eq!(m.node_ids, [10, 30, 20, 40, 50]);
    assert_eq!(m.nodes[1], Point3::new(1.0, 0.0, 0.0));
    assert_eq!(m.nodes[3], Point3::new(0.0, 0.0, 1.0)); // Fortran exponent 1D0
    assert_eq!(m.element_ids, [7, 3]);
    assert_eq!(m.elements[0], Element::tet4([0, 1, 2, 3]));
    assert_eq!(m.elements[1], Element::tet4([1, 2, 3, 4]));
    // Set names as first written; lookups case-insensitive.
    assert_eq!(m.element_sets.keys().collect::<Vec<_>>(), ["Brain"]);
    assert_eq!(m.element_set("brain").unwrap(), [0, 1]);
    assert_eq!(m.node_set("ALLN").unwrap(), [0, 1, 2, 3, 4]);
    assert_eq!(m.node_set("Fixed").unwrap(), [0, 2]);
    // GENERATE 10, 50, 20 → ids 10, 30, 50 → indices 0, 1, 4.
    assert_eq!(m.node_set("gen").unwrap(), [0, 1, 4]);
    assert_eq!(m.node_set("fromEl").unwrap(), [0, 1, 2, 3, 4]);
    assert_eq!(m.node_set("merged").unwrap(), [0, 2, 4]);
}

#[test]
fn inp_hex_with_continuation_and_c3d8r() {
    let mut deck = String::from("*NODE\n");
    let corners =
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]];
    for (i, c) in corners.iter().enumerate() {
        deck += &format!("{}, {}, {}, {}\n", i + 1, c[0] * 2, c[1] * 3, c[2] * 4);
    }
    deck += "*ELEMENT, TYPE=C3D8R\n1, 1, 2, 3, 4,\n5, 6, 7, 8\n";
    let m = inp_str(&deck).unwrap();
    assert_eq!(m.elements, [Element::hex8([0, 1, 2, 3, 4, 5, 6, 7])]);
    // A 2×3×4 box.
    assert!((m.element_volume(0) - 24.0).abs() < 1e-12);
}

fn err_at(r: Result<Mesh, ParseError>, line: usize, needles: &[&str]) -> ParseError {
    let e = r.expect_err("expected a parse error");
    assert_eq!(e.location, Location::Line(line), "{e}");
    let text = e.to_string();
    for n in needles {
        assert!(text.contains(n), "'{text}' lacks '{n}'");
    }
    e
}

const TET_NODES: &str = "*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n3, 0, 1, 0\n4, 0, 0, 1\n";

#[test]
fn inp_errors_name_line_and_fix() {
    let e = err_at(
        inp_str(&format!("{TET_NODES}*ELEMENT, TYPE=C3D10\n1, 1, 2, 3, 4, 1, 2, 3, 4, 1, 2\n")),
        6,
        &["test.inp:6:", "C3D10", "quadratic", "convert to linear C3D4"],
    );
    assert_eq!(e.file, Path::new("test.inp"));
    err_at(
        inp_str(&format!("{TET_NODES}*ELEMENT, TYPE=C3D4\n1, 1, 2, 3, 9\n")),
        7,
        &["element 1", "node 9"],
    );
    err_at(inp_str(&format!("{TET_NODES}3, 5, 5, 5\n")), 6, &["duplicate node id 3", "line 4"]);
    err_at(
        inp_str(&format!("{TET_NODES}*ELEMENT, TYPE=C3D4\n1, 1, 2, 3, 4\n** c\n1, 1, 2, 4, 3\n")),
        9,
        &["duplicate element id 1", "line 7"],
    );
    err_at(
        inp_str(&format!("{TET_NODES}*ELEMENT, TYPE=C3D4\n1, 1, 2, 3\n")),
        7,
        &["3 node ids", "needs 4"],
    );
    err_at(inp_str(&format!("{TET_NODES}*NSET, NSET=A\n1, 7\n")), 7, &["'A'", "node 7"]);
    err_at(inp_str("*NODE\n1, 0, zero, 0\n"), 2, &["coordinate", "'zero'"]);
    err_at(inp_str("1, 2, 3\n"), 1, &["keyword"]);
    err_at(inp_str(&format!("{TET_NODES}*ELEMENT\n")), 6, &["TYPE="]);
    err_at(inp_str(&format!("{TET_NODES}*ELEMENT, TYPE=XYZ9\n")), 6, &["XYZ9"]);
    err_at(inp_str(&format!("{TET_NODES}*NSET, NSET=G, GENERATE\n4, 1\n")), 7, &["GENERATE"]);
    err_at(inp_str(&format!("{TET_NODES}*ELEMENT, TYPE=C3D4\n1, 1, 2,\n")), 7, &["continuation"]);
    err_at(inp_str("*INCLUDE, INPUT=other.inp\n"), 1, &["*INCLUDE"]);
    err_at(inp_str(&format!("{TET_NODES}*ELSET, ELSET=E\n\n5\n")), 8, &["'E'", "element 5"]);
    err_at(inp_str(&format!("{TET_NODES}*NSET, NSET=N\n1, other\n")), 7, &["'other'"]);
}

const MSH41_HEAD: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
const MSH41_NODES: &str =
    "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n";

#[test]
fn msh41_minimal_with_unnamed_groups_and_skipped_sections() {
    let text = format!(
        "{MSH41_HEAD}$Entities\n0 0 1 1\n1 0 0 0 1 1 0 1 8 0\n1 0 0 0 1 1 1 1 5 0\n$EndEntities\n\
         {MSH41_NODES}$Periodic\n0\n$EndPeriodic\n$Elements\n2 2 1 2\n\
         2 1 2 1\n1 1 2 3\n3 1 4 1\n2 1 2 3 4\n$EndElements\n$NodeData\n1\n\"u\"\n$EndNodeData\n"
    );
    let m = msh_str(&text).unwrap();
    assert_eq!(m.elements, [Element::tet4([0, 1, 2, 3])]);
    assert_eq!(m.element_ids, [2]);
    assert_eq!(m.element_sets.keys().collect::<Vec<_>>(), ["PHYSICAL_5"]);
    assert_eq!(m.node_set("PHYSICAL_2D_8").unwrap(), [0, 1, 2]);
    assert_eq!(m.node_set("PHYSICAL_5").unwrap(), [0, 1, 2, 3]);
}

#[test]
fn msh22_repeated_element_joins_second_group() {
    let text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n3 1 \"brain tissue\"\n\
                3 2 \"B\"\n$EndPhysicalNames\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n\
                4 0 0 1\n$Elements\n";
    // Missing $EndNodes → error naming the line where it was expected.
    err_at(msh_str(text), 15, &["$EndNodes"]);
    let text = text.replace("$Elements\n", "$EndNodes\n$Elements\n3\n")
        + "7 4 2 1 1 1 2 3 4\n7 4 2 2 1 1 2 3 4\n8 15 2 2 3 4\n$EndElements\n";
    let m = msh_str(&text).unwrap();
    assert_eq!(m.elements.len(), 1);
    assert_eq!(m.element_set("brain tissue").unwrap(), [0]);
    assert_eq!(m.element_set("B").unwrap(), [0]);
    assert_eq!(m.node_set("PHYSICAL_0D_2").unwrap(), [3]);
    // The same tag with other nodes is an error naming both lines.
    let bad = text.replace("7 4 2 2 1 1 2 3 4", "7 4 2 2 1 1 2 4 3");
    err_at(msh_str(&bad), 19, &["duplicate element tag 7", "line 18"]);
}

#[test]
fn msh_errors_name_line_and_fix() {
    // Binary files are read (tests/msh_binary.rs); one without sections lacks $Nodes.
    let e = msh_str("$MeshFormat\n4.1 1 8\n\u{1}\0\0\0\n$EndMeshFormat\n").unwrap_err();
    assert_eq!(e.location, Location::File);
    assert!(e.to_string().contains("no $Nodes"), "{e}");
    err_at(msh_str("$MeshFormat\n4.1 2 8\n$EndMeshFormat\n"), 2, &["file-type 0 (ASCII) or 1"]);
    err_at(msh_str("$MeshFormat\n4.0 0 8\n$EndMeshFormat\n"), 2, &["4.0", "4.1 or 2.2"]);
    err_at(msh_str("hello\n"), 1, &["$MeshFormat"]);
    let tet10 = format!(
        "{MSH41_HEAD}{MSH41_NODES}$Elements\n1 1 1 1\n3 1 11 1\n1 1 2 3 4 1 2 3 4 1 2\n$EndElements\n"
    );
    err_at(msh_str(&tet10), 18, &["test.msh:18:", "type 11", "second-order", "-order 1"]);
    let unknown_node =
        format!("{MSH41_HEAD}{MSH41_NODES}$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 9\n$EndElements\n");
    err_at(msh_str(&unknown_node), 19, &["element 1", "node 9"]);
    let dup = MSH41_NODES.replace("\n4\n0 0 0", "\n1\n0 0 0");
    err_at(msh_str(&format!("{MSH41_HEAD}{dup}")), 10, &["duplicate node tag 1", "line 7"]);
    let short = format!("{MSH41_HEAD}{MSH41_NODES}$Elements\n1 1 1 1\n3 1 5 1\n1 1 2 3 4\n");
    err_at(msh_str(&short), 19, &["lists 4 node tags, expected 8"]);
    let truncated = format!("{MSH41_HEAD}{}", &MSH41_NODES[..37]);
    err_at(msh_str(&truncated), 11, &["unexpected end of file"]);
    err_at(msh_str(&format!("{MSH41_HEAD}$PartitionedEntities\n2\n")), 4, &["partition"]);
    let e = msh_str(&format!("{MSH41_HEAD}{MSH41_NODES}")).unwrap_err();
    assert_eq!(e.location, Location::File);
    assert!(e.to_string().contains("$Elements"));
}

/// Deterministic corruptions of a fixture, driven by proptest.
#[derive(Debug, Clone)]
enum Mutation {
    Flip { at: usize, byte: u8 },
    DeleteLine(usize),
    DuplicateLine(usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Mutation::Flip { at, byte }),
        // Printable bytes that matter to the parsers.
        (any::<usize>(), prop::sample::select(b"0123456789-.,* \n$eE\"".to_vec()))
            .prop_map(|(at, byte)| Mutation::Flip { at, byte }),
        any::<usize>().prop_map(Mutation::DeleteLine),
        any::<usize>().prop_map(Mutation::DuplicateLine),
    ]
}

fn apply(bytes: &[u8], mutations: &[Mutation]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for m in mutations {
        match *m {
            Mutation::Flip { at, byte } => {
                if !b.is_empty() {
                    let n = b.len();
                    b[at % n] = byte;
                }
            }
            Mutation::DeleteLine(k) | Mutation::DuplicateLine(k) => {
                let mut lines: Vec<Vec<u8>> =
                    b.split(|&c| c == b'\n').map(<[u8]>::to_vec).collect();
                let i = k % lines.len();
                if matches!(m, Mutation::DeleteLine(_)) {
                    lines.remove(i);
                } else {
                    let l = lines[i].clone();
                    lines.insert(i, l);
                }
                b = lines.join(&b'\n');
            }
        }
    }
    b
}

const FIXTURES: [&str; 7] = [
    "cube-t4.msh",
    "cube-t4-v22.msh",
    "cube-t4.inp",
    "cube-h8.msh",
    "cube-h8-v22.msh",
    "cube-h8.inp",
    "sphere.msh",
];

fn read_any(name: &str, bytes: &[u8]) -> Result<Mesh, ParseError> {
    // Feed every corrupted file to both readers: the wrong one must fail cleanly too.
    let p = Path::new(name);
    let a = inp::read(bytes, p);
    let b = msh::read(bytes, p);
    if name.ends_with(".inp") { a } else { b }
}

proptest! {
    // Default 256 cases (override with PROPTEST_CASES for a longer hunt).
    #[test]
    fn truncated_fixtures_never_panic(f in 0..FIXTURES.len(), cut in any::<usize>()) {
        let bytes = fixture(FIXTURES[f]);
        let cut = cut % (bytes.len() + 1);
        let r = read_any(FIXTURES[f], &bytes[..cut]);
        // A prefix that still parses is a smaller mesh of the same file.
        if let Ok(m) = r {
            let full = read_fixture(FIXTURES[f]);
            prop_assert!(m.nodes.len() <= full.nodes.len());
        }
    }

    #[test]
    fn mutated_fixtures_never_panic(
        f in 0..FIXTURES.len(),
        muts in prop::collection::vec(mutation(), 1..6),
    ) {
        let bytes = apply(&fixture(FIXTURES[f]), &muts);
        if let Ok(m) = read_any(FIXTURES[f], &bytes) {
            // Whatever parsed is internally consistent.
            prop_assert_eq!(m.node_ids.len(), m.nodes.len());
            prop_assert_eq!(m.element_ids.len(), m.elements.len());
            for e in &m.elements {
                prop_assert!(e.nodes().iter().all(|&n| n < m.nodes.len()));
            }
            for s in m.node_sets.values() {
                prop_assert!(s.windows(2).all(|w| w[0] < w[1]));
                prop_assert!(s.iter().all(|&n| n < m.nodes.len()));
            }
            for s in m.element_sets.values() {
                prop_assert!(s.windows(2).all(|w| w[0] < w[1]));
                prop_assert!(s.iter().all(|&n| n < m.elements.len()));
            }
        }
    }
}

/// A random small mesh with unique sparse ids, arbitrary finite coordinates (including
/// signed zeros, subnormals and extremes) and named sets.
fn random_mesh() -> impl Strategy<Value = Mesh> {
    let coord = prop_oneof![
        any::<f64>().prop_filter("finite", |c| c.is_finite()),
        -1e3..1e3f64,
        Just(-0.0),
        Just(f64::MIN_POSITIVE / 8.0),
        Just(f64::MAX),
    ];
    (1usize..12).prop_flat_map(move |nn| {
        let nodes = prop::collection::vec([coord.clone(), coord.clone(), coord.clone()], nn);
        let node_ids = prop::collection::btree_set(1u64..u64::MAX, nn).prop_shuffle_ids();
        let elements =
            prop::collection::vec((any::<bool>(), prop::collection::vec(0..nn, 8)), 0..10);
        (nodes, node_ids, elements).prop_flat_map(move |(nodes, node_ids, elements)| {
            let ne = elements.len();
            let element_ids = prop::collection::btree_set(0u64..1_000_000, ne).prop_shuffle_ids();
            let node_sets = prop::collection::btree_map(
                "[A-Z][A-Z0-9_]{0,6}",
                prop::collection::btree_set(0..nn, 0..=nn),
                0..4,
            );
            let element_sets = if ne == 0 {
                Just(BTreeMap::new()).boxed()
            } else {
                prop::collection::btree_map(
                    "[A-Z][A-Z0-9_]{0,6}",
                    prop::collection::btree_set(0..ne, 0..=ne),
                    0..4,
                )
                .boxed()
            };
            let nodes = nodes.clone();
            let node_ids = node_ids.clone();
            let elements = elements.clone();
            (element_ids, node_sets, element_sets).prop_map(move |(eids, ns, es)| Mesh {
                nodes: nodes.iter().map(|c| Point3::new(c[0], c[1], c[2])).collect(),
                node_ids: node_ids.clone(),
                elements: elements
                    .iter()
                    .map(|(tet, n)| {
                        if *tet {
                            Element::tet4([n[0], n[1], n[2], n[3]])
                        } else {
                            Element::hex8([n[0], n[1], n[2], n[3], n[4], n[5], n[6], n[7]])
                        }
                    })
                    .collect(),
                element_ids: eids,
                node_sets: ns.into_iter().map(|(k, v)| (k, v.into_iter().collect())).collect(),
                element_sets: es.into_iter().map(|(k, v)| (k, v.into_iter().collect())).collect(),
            })
        })
    })
}

/// Turns a set of unique ids into a shuffled `Vec` (ids need not be sorted in a deck).
trait ShuffleIds {
    fn prop_shuffle_ids(self) -> BoxedStrategy<Vec<u64>>;
}

impl<S: Strategy<Value = BTreeSet<u64>> + 'static> ShuffleIds for S {
    fn prop_shuffle_ids(self) -> BoxedStrategy<Vec<u64>> {
        self.prop_map(|s| s.into_iter().collect::<Vec<_>>()).prop_shuffle().boxed()
    }
}

/// Checks a read-back coordinate against the original: bitwise equal where the writer
/// promises exactness (see the inp module docs), else within the 14-significant-digit
/// rounding bound.
fn check_coordinate(written: f64, read: f64) -> Result<(), TestCaseError> {
    let a = written.abs();
    let exact = format!("{written:?}").len() <= 20 || a == 0.0 || (0.01..1e16).contains(&a);
    if exact {
        prop_assert_eq!(read.to_bits(), written.to_bits(), "{:?} read back as {:?}", written, read);
    } else {
        prop_assert!((read - written).abs() <= 1e-13 * a, "{:?} read back as {:?}", written, read);
    }
    Ok(())
}

/// The coordinate fields of the `*NODE` block of a written deck.
fn coordinate_fields(deck: &str) -> Vec<String> {
    deck.lines()
        .skip_while(|l| *l != "*NODE")
        .skip(1)
        .take_while(|l| !l.starts_with('*'))
        .flat_map(|l| l.split(", ").skip(1).map(str::to_string).collect::<Vec<_>>())
        .collect()
}

proptest! {
    #[test]
    fn inp_write_read_round_trip(mesh in random_mesh()) {
        let mut buf = Vec::new();
        inp::write(&mut buf, &mesh).unwrap();
        let text = String::from_utf8(buf).unwrap();
        // CalculiX reads 20 characters per coordinate and 132 per line.
        for f in coordinate_fields(&text) {
            prop_assert!(f.len() <= 20, "{}", f);
        }
        prop_assert!(text.lines().all(|l| l.len() <= 132));
        let back = inp::read(text.as_bytes(), Path::new("rt.inp")).unwrap();
        prop_assert_eq!(back.nodes.len(), mesh.nodes.len());
        for (p, q) in mesh.nodes.iter().zip(&back.nodes) {
            for k in 0..3 {
                check_coordinate(p[k], q[k])?;
            }
        }
        // Everything else is exact.
        let same_coords = Mesh { nodes: mesh.nodes.clone(), ..back };
        prop_assert_eq!(&same_coords, &mesh);
    }

    #[test]
    fn coordinates_fit_calculix_and_round_trip(x in any::<f64>().prop_filter("finite", |x| x.is_finite())) {
        let mesh = Mesh::new(vec![Point3::new(x, -x, x / 3.0)], Vec::new());
        let mut buf = Vec::new();
        inp::write(&mut buf, &mesh).unwrap();
        let text = String::from_utf8(buf).unwrap();
        for f in coordinate_fields(&text) {
            prop_assert!(f.len() <= 20, "{}", f);
        }
        let back = inp::read(text.as_bytes(), Path::new("x.inp")).unwrap();
        for k in 0..3 {
            check_coordinate(mesh.nodes[0][k], back.nodes[0][k])?;
        }
    }
}

#[test]
fn hard_coordinates_fit_twenty_characters() {
    // Values whose shortest round-trip text is longer than 20 characters.
    // Expected texts: the exact digits when they fit (dropping the leading 0, or as an
    // integer mantissa), else rounded to 16 (or 14 with a 3-digit exponent) digits; next to
    // f64::MAX rounding up would overflow, so the digits are cut.
    let cases = [
        (-0.012345678901234567, "-.012345678901234567"),
        (1.2345678901234568e-5, "1234567890123457e-20"),
        (-1.2345678901234567e-100, "-12345678901235e-113"),
        (5e-324, "5e-324"),
        (f64::MAX, "1797693134862315e293"),
        (-f64::MAX, "-179769313486231e294"),
    ];
    for (x, expected) in cases {
        let m = Mesh::new(vec![Point3::new(x, 0.0, 0.0)], Vec::new());
        let mut buf = Vec::new();
        inp::write(&mut buf, &m).unwrap();
        let text = String::from_utf8(buf).unwrap();
        let field = &coordinate_fields(&text)[0];
        assert_eq!(field, expected);
        assert!(field.len() <= 20, "{field}");
        let back: f64 = field.parse().unwrap();
        // Exactly representable within 20 characters: bitwise; otherwise 14+ digits.
        let exact = format!("{x:?}").len() <= 20 || (0.01..1e16).contains(&x.abs());
        if exact {
            assert_eq!(back.to_bits(), x.to_bits(), "{field}");
        } else {
            assert!((back - x).abs() <= 1e-13 * x.abs(), "{field}");
        }
    }
}

#[test]
fn inp_writer_layout_and_rejections() {
    let mut m = Mesh::new(
        (0..20).map(|i| Point3::new(f64::from(i), 0.1, -0.0)).collect(),
        vec![Element::tet4([0, 1, 2, 3]), Element::hex8([0, 1, 2, 3, 4, 5, 6, 7])],
    );
    m.node_sets.insert("ALL".into(), (0..20).collect());
    m.element_sets.insert("my set".into(), vec![1]);
    let mut buf = Vec::new();
    inp::write(&mut buf, &m).unwrap();
    let text = String::from_utf8(buf).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[1], "*NODE");
    assert_eq!(lines[2], "1, 0.0, 0.1, -0.0");
    assert_eq!(lines[22], "*ELEMENT, TYPE=C3D4");
    assert_eq!(lines[23], "1, 1, 2, 3, 4");
    assert_eq!(lines[24], "*ELEMENT, TYPE=C3D8");
    assert_eq!(lines[26], "*NSET, NSET=ALL");
    // 16 ids per line.
    assert_eq!(lines[27], (1..=16).map(|i| i.to_string()).collect::<Vec<_>>().join(", "));
    assert_eq!(lines[28], "17, 18, 19, 20");
    assert_eq!(lines[29], "*ELSET, ELSET=\"my set\"");
    assert_eq!(inp_str(&text).unwrap(), m);

    let mut bad = m.clone();
    bad.node_sets.insert("all".into(), vec![0]);
    assert!(inp::write(&mut Vec::new(), &bad).unwrap_err().to_string().contains("case"));
    let mut bad = m.clone();
    bad.node_ids[3] = 1;
    assert!(inp::write(&mut Vec::new(), &bad).unwrap_err().to_string().contains("duplicate"));
    let mut bad = m;
    bad.node_sets.insert("A,B".into(), vec![0]);
    assert!(inp::write(&mut Vec::new(), &bad).is_err());
}

/// Text written by Windows editors may start with a UTF-8 byte-order mark: it is skipped and
/// the line numbers of errors are unchanged.
#[test]
fn byte_order_mark_is_skipped_by_inp_and_msh() {
    const BOM: &[u8] = b"\xEF\xBB\xBF";
    for name in ["cube-t4.inp", "cube-t4.msh", "cube-t4-v22.msh"] {
        let path = fixture_path(name);
        let with_bom = [BOM, fixture(name).as_slice()].concat();
        let r = if name.ends_with(".inp") {
            inp::read(&with_bom, &path)
        } else {
            msh::read(&with_bom, &path)
        };
        assert_eq!(r.unwrap_or_else(|e| panic!("{e}")), read_fixture(name), "{name}");
    }
    let deck = [BOM, b"*NODE\n1, 0, 0, 0\n2, x, 0, 0\n".as_slice()].concat();
    let e = inp::read(&deck, Path::new("t.inp")).unwrap_err();
    assert_eq!(e.location, Location::Line(3));
}
