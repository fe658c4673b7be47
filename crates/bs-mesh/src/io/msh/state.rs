//! What the ASCII and the binary `.msh` readers share: the gmsh element types, the state
//! both fill (nodes, elements, physical groups, 4.1 blocks) and the mesh and sets built from
//! it, so that both formats give the same [`Mesh`].

use std::collections::hash_map::Entry;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use nalgebra::Point3;

use crate::io::inp::snippet;
use crate::io::{Location, ParseError};
use crate::{Element, Mesh};

/// Dimension, node count and description of the gmsh element types brainshift knows.
pub(super) fn element_type(t: u32) -> Option<(u8, usize, &'static str)> {
    Some(match t {
        1 => (1, 2, "2-node line"),
        2 => (2, 3, "3-node triangle"),
        3 => (2, 4, "4-node quadrangle"),
        4 => (3, 4, "4-node tetrahedron"),
        5 => (3, 8, "8-node hexahedron"),
        6 => (3, 6, "6-node prism"),
        7 => (3, 5, "5-node pyramid"),
        8 => (1, 3, "3-node second-order line"),
        9 => (2, 6, "6-node second-order triangle"),
        10 => (2, 9, "9-node second-order quadrangle"),
        11 => (3, 10, "10-node second-order tetrahedron"),
        12 => (3, 27, "27-node second-order hexahedron"),
        13 => (3, 18, "18-node second-order prism"),
        14 => (3, 14, "14-node second-order pyramid"),
        15 => (0, 1, "1-node point"),
        16 => (2, 8, "8-node second-order quadrangle"),
        17 => (3, 20, "20-node second-order hexahedron"),
        18 => (3, 15, "15-node second-order prism"),
        19 => (3, 13, "13-node second-order pyramid"),
        20 => (2, 9, "9-node third-order incomplete triangle"),
        21 => (2, 10, "10-node third-order triangle"),
        22 => (2, 12, "12-node fourth-order incomplete triangle"),
        23 => (2, 15, "15-node fourth-order triangle"),
        24 => (2, 15, "15-node fifth-order incomplete triangle"),
        25 => (2, 21, "21-node fifth-order triangle"),
        26 => (1, 4, "4-node third-order line"),
        27 => (1, 5, "5-node fourth-order line"),
        28 => (1, 6, "6-node fifth-order line"),
        29 => (3, 20, "20-node third-order tetrahedron"),
        30 => (3, 35, "35-node fourth-order tetrahedron"),
        31 => (3, 56, "56-node fifth-order tetrahedron"),
        _ => return None,
    })
}

pub(super) fn unsupported_3d(t: u32, what: &str) -> String {
    format!(
        "gmsh element type {t} ({what}) is not supported: brainshift solves linear tetrahedra \
         (type 4) and hexahedra (type 5) only; remesh with first-order tets, e.g. `gmsh \
         model.geo -3 -order 1 -format msh41 -o mesh.msh` (Mesh.ElementOrder = 1, no \
         Mesh.RecombineAll for prisms/pyramids)"
    )
}

/// Members of one physical group `(dim, tag)`.
#[derive(Debug, Default)]
pub(super) struct Group {
    pub(super) elements: Vec<usize>,
    pub(super) nodes: Vec<usize>,
}

/// A 4.1 element block, resolved to physical groups once the whole file is read.
#[derive(Debug)]
pub(super) struct Block {
    pub(super) dim: u8,
    pub(super) entity: i64,
    /// Element index range (3D blocks).
    pub(super) elements: std::ops::Range<usize>,
    /// Range into `State::lower_nodes` (0D–2D blocks).
    pub(super) nodes: std::ops::Range<usize>,
}

/// Everything read so far; shared by the ASCII and the binary reader so that both build the
/// mesh and its sets the same way ([`finish`]).
#[derive(Debug, Default)]
pub(super) struct State {
    pub(super) nodes: Vec<Point3<f64>>,
    pub(super) node_ids: Vec<u64>,
    /// Where each node was defined (line or byte offset), for duplicate-tag errors.
    pub(super) node_locs: Vec<Location>,
    pub(super) node_map: HashMap<u64, usize>,
    pub(super) elements: Vec<Element>,
    pub(super) element_ids: Vec<u64>,
    pub(super) element_locs: Vec<Location>,
    pub(super) element_map: HashMap<u64, usize>,
    pub(super) physical_names: HashMap<(u8, i64), String>,
    /// 4.1: physical tags of each entity `(dim, tag)`.
    pub(super) entities: HashMap<(u8, i64), Vec<i64>>,
    pub(super) groups: BTreeMap<(u8, i64), Group>,
    pub(super) blocks: Vec<Block>,
    pub(super) lower_nodes: Vec<usize>,
    pub(super) seen_nodes: bool,
    pub(super) seen_elements: bool,
}

/// "on line 7" or "at byte 120": where an earlier definition was.
fn describe(loc: Location) -> String {
    match loc {
        Location::Line(l) => format!("on line {l}"),
        Location::Byte(b) => format!("at byte {b}"),
        Location::File => "earlier in the file".into(),
    }
}

/// The mesh, once the whole file was read; an error when a required section was missing.
pub(super) fn complete(st: State, file: &Path) -> Result<Mesh, ParseError> {
    if !st.seen_nodes {
        return Err(ParseError::new(file, Location::File, "no $Nodes section found"));
    }
    if !st.seen_elements {
        return Err(ParseError::new(file, Location::File, "no $Elements section found"));
    }
    Ok(finish(st))
}

/// Parses a `$PhysicalNames` entry `dim tag "name"` (ASCII in binary files too).
pub(super) fn physical_name(t: &str) -> Result<((u8, i64), String), String> {
    let mut f = t.split_ascii_whitespace();
    let mut next =
        |what: &str| f.next().ok_or_else(|| format!("expected {what}, found the end of the line"));
    let dim = next("a dimension (0 to 3)")?;
    let dim: u8 =
        dim.parse().map_err(|_| format!("expected a dimension (0 to 3), found '{dim}'"))?;
    let tag = next("a physical tag")?;
    let tag: i64 = tag.parse().map_err(|_| format!("expected a physical tag, found '{tag}'"))?;
    if dim > 3 {
        return Err(format!("expected a dimension 0 to 3, found {dim}"));
    }
    // The name is the rest of the line, in double quotes (it may hold spaces).
    let rest = t.find('"').map(|i| &t[i..]).unwrap_or("");
    let name = rest
        .strip_prefix('"')
        .and_then(|r| r.strip_suffix('"'))
        .ok_or_else(|| format!("expected 'dim tag \"name\"', found '{}'", snippet(t)))?;
    Ok(((dim, tag), name.to_string()))
}

/// Adds node `id` defined at `at`; a repeated tag is an error naming both places.
pub(super) fn add_node(
    file: &Path,
    st: &mut State,
    id: u64,
    p: Point3<f64>,
    at: Location,
) -> Result<(), ParseError> {
    let idx = st.nodes.len();
    match st.node_map.entry(id) {
        Entry::Occupied(o) => {
            let first = describe(st.node_locs[*o.get()]);
            return Err(ParseError::new(
                file,
                at,
                format!("duplicate node tag {id}: already defined {first}"),
            ));
        }
        Entry::Vacant(v) => {
            v.insert(idx);
        }
    }
    st.nodes.push(p);
    st.node_ids.push(id);
    st.node_locs.push(at);
    Ok(())
}

/// The index of node tag `nid` used by element `el` (defined at `at`).
pub(super) fn node_index(
    file: &Path,
    st: &State,
    at: Location,
    el: u64,
    nid: u64,
) -> Result<usize, ParseError> {
    st.node_map.get(&nid).copied().ok_or_else(|| {
        ParseError::new(
            file,
            at,
            format!("element {el} references node {nid}, which $Nodes does not define"),
        )
    })
}

/// Adds a tet4/hex8 element and returns its index; with `allow_repeat` (2.2) a repeated tag
/// with identical nodes returns the earlier index instead of an error.
pub(super) fn add_element(
    file: &Path,
    st: &mut State,
    id: u64,
    el: Element,
    at: Location,
    allow_repeat: bool,
) -> Result<usize, ParseError> {
    let idx = st.elements.len();
    match st.element_map.entry(id) {
        Entry::Occupied(o) => {
            let prev = *o.get();
            if allow_repeat && st.elements[prev] == el {
                return Ok(prev);
            }
            let first = describe(st.element_locs[prev]);
            return Err(ParseError::new(
                file,
                at,
                format!("duplicate element tag {id}: already defined {first}"),
            ));
        }
        Entry::Vacant(v) => {
            v.insert(idx);
        }
    }
    st.elements.push(el);
    st.element_ids.push(id);
    st.element_locs.push(at);
    Ok(idx)
}

pub(super) fn build_element(kind_type: u32, idx: &[usize]) -> Element {
    if kind_type == 4 {
        Element::tet4([idx[0], idx[1], idx[2], idx[3]])
    } else {
        let mut n = [0; 8];
        n.copy_from_slice(&idx[..8]);
        Element::hex8(n)
    }
}

fn finish(mut st: State) -> Mesh {
    // 4.1: element blocks get their physical groups from $Entities.
    for b in &st.blocks {
        let Some(tags) = st.entities.get(&(b.dim, b.entity)) else { continue };
        for &p in tags {
            let g = st.groups.entry((b.dim, p)).or_default();
            if b.dim == 3 {
                g.elements.extend(b.elements.clone());
            } else {
                g.nodes.extend_from_slice(&st.lower_nodes[b.nodes.clone()]);
            }
        }
    }
    let mut node_sets: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    let mut element_sets: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for ((dim, tag), g) in std::mem::take(&mut st.groups) {
        let name = match st.physical_names.get(&(dim, tag)) {
            Some(n) => n.clone(),
            None if dim == 3 => format!("PHYSICAL_{tag}"),
            None => format!("PHYSICAL_{dim}D_{tag}"),
        };
        let nodes = node_sets.entry(name.clone()).or_default();
        nodes.extend_from_slice(&g.nodes);
        for &e in &g.elements {
            nodes.extend_from_slice(st.elements[e].nodes());
        }
        if dim == 3 {
            element_sets.entry(name).or_default().extend_from_slice(&g.elements);
        }
    }
    for v in node_sets.values_mut().chain(element_sets.values_mut()) {
        v.sort_unstable();
        v.dedup();
    }
    Mesh {
        nodes: st.nodes,
        node_ids: st.node_ids,
        elements: st.elements,
        element_ids: st.element_ids,
        node_sets,
        element_sets,
    }
}
