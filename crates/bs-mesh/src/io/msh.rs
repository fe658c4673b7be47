//! Gmsh meshes (`.msh`), versions 4.1 and 2.2 (2.0 and 2.1 read as 2.2), ASCII or binary.
//!
//! * The version and file type come from `$MeshFormat`; versions 1, 3 and 4.0 are rejected
//!   with the fix. Binary files (file type 1, either byte order) are read by
//!   `msh_binary.rs` into the same [`Mesh`] as the ASCII file of the same
//!   mesh; their errors name byte offsets instead of lines.
//! * `$PhysicalNames`, `$Entities` (4.1: which physical groups each entity belongs to),
//!   `$Nodes` and `$Elements` are read; every other section (`$Periodic`, `$NodeData`, …) is
//!   skipped. `$Nodes` must come before `$Elements` (gmsh always writes it so). Partitioned
//!   4.1 files (`$PartitionedEntities`) are rejected: save without partitions.
//! * Element types 4 (4-node tetrahedron) and 5 (8-node hexahedron) become elements; gmsh's
//!   node orders for both equal the Abaqus/VTK orders used by [`Mesh`]. Other 3D types
//!   (second-order tets 11, hexes 12/17, prisms, pyramids) are rejected with the fix.
//!   Points, lines, triangles and quadrangles (types 15, 1, 2, 3 and their higher-order
//!   versions) are not elements; their nodes go into the node sets of their physical groups.
//! * Physical groups become sets: a 3D group becomes an element set named by its physical
//!   name (`PHYSICAL_<tag>` when unnamed) and a node set of its elements' nodes; a 0D/1D/2D
//!   group becomes a node set of its elements' nodes (`PHYSICAL_<dim>D_<tag>` when unnamed,
//!   so that it cannot merge with a 3D group of the same tag). Groups of any dimension that
//!   share a name share the set.
//! * Version 2.2 writes an element once per physical group it belongs to (same tag and
//!   nodes); such repeats add group membership. Any other repeated node or element tag is an
//!   error naming both lines.

use std::collections::hash_map::Entry;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use nalgebra::Point3;

use super::inp::snippet;
use super::{Lines, Location, ParseError, parse_field};
use crate::{Element, Mesh};

/// The supported file layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Version {
    V2,
    V4,
}

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

/// What the `$MeshFormat` header says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Header {
    /// File layout version.
    pub(super) version: Version,
    /// File type 1 (binary) rather than 0 (ASCII).
    pub(super) binary: bool,
    /// The data-size field: bytes of a `size_t` in binary 4.1 files (4 or 8).
    pub(super) data_size: usize,
    /// Byte offset just past the header line (where a binary file's endianness int starts).
    pub(super) end: usize,
}

/// Reads the version and file type from the `$MeshFormat` header straight from the bytes, so
/// that binary files (not UTF-8) are recognised before any text decoding.
fn sniff(bytes: &[u8], file: &Path) -> Result<Header, ParseError> {
    let err = |line, msg: String| ParseError::new(file, Location::Line(line), msg);
    let mut rest = super::strip_bom(bytes);
    let total = bytes.len();
    let mut line_no = 0;
    let mut next_line = || -> Option<&[u8]> {
        loop {
            if rest.is_empty() {
                return None;
            }
            let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            let l = &rest[..end];
            rest = &rest[(end + 1).min(rest.len())..];
            line_no += 1;
            if !l.trim_ascii().is_empty() {
                return Some(l.trim_ascii());
            }
        }
    };
    let first = next_line();
    if first != Some(b"$MeshFormat".as_slice()) {
        return Err(ParseError::new(
            file,
            Location::Line(1),
            "expected '$MeshFormat' on the first line: this is not a gmsh .msh file (or it is \
             gmsh 1.0, which is not supported: save as version 4.1 or 2.2)",
        ));
    }
    let header = next_line();
    let ln = line_no;
    let end = total - rest.len();
    let header = header.and_then(|h| std::str::from_utf8(h).ok()).ok_or_else(|| {
        err(ln, "expected 'version file-type data-size' (e.g. '4.1 0 8') after $MeshFormat".into())
    })?;
    let mut f = header.split_ascii_whitespace();
    let version = f.next().unwrap_or("");
    let file_type = f.next().unwrap_or("");
    let binary = match file_type {
        "0" => false,
        "1" => true,
        _ => {
            let msg = format!(
                "expected file-type 0 (ASCII) or 1 (binary) in '{}' (format 'version file-type \
                 data-size')",
                snippet(header)
            );
            return Err(err(ln, msg));
        }
    };
    let data_size = match f.next().map(str::parse::<usize>) {
        Some(Ok(n @ (4 | 8))) => n,
        _ if !binary => 8,
        _ => {
            return Err(err(
                ln,
                format!(
                    "expected data-size 4 or 8 (bytes of size_t) in '{}'; re-save the binary \
                     file with gmsh on a 32- or 64-bit machine",
                    snippet(header)
                ),
            ));
        }
    };
    let version = match version {
        "4.1" => Version::V4,
        "2" | "2.0" | "2.1" | "2.2" => Version::V2,
        v => {
            return Err(err(
                ln,
                format!(
                    "gmsh format version '{}' is not supported; save as 4.1 or 2.2 ASCII (`gmsh \
                 mesh.msh -save -format msh41 -o new.msh`)",
                    snippet(v)
                ),
            ));
        }
    };
    Ok(Header { version, binary, data_size, end })
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

/// A count from line `ln` of items taking at least `min_bytes` bytes each: refused when the
/// whole file (`size` bytes) cannot hold them, so that a corrupt count never drives an
/// allocation (the count is then also a safe capacity).
fn count(
    lines: &Lines<'_>,
    ln: usize,
    n: usize,
    min_bytes: usize,
    size: usize,
    what: &str,
) -> Result<usize, ParseError> {
    let need = n as u128 * min_bytes as u128;
    if need > size as u128 {
        return Err(lines.error(
            ln,
            format!(
                "the file declares {n} {what}, which need at least {need} bytes, but it has \
                 {size} bytes; the count is corrupt or the file is truncated"
            ),
        ));
    }
    Ok(n)
}

/// "on line 7" or "at byte 120": where an earlier definition was.
fn describe(loc: Location) -> String {
    match loc {
        Location::Line(l) => format!("on line {l}"),
        Location::Byte(b) => format!("at byte {b}"),
        Location::File => "earlier in the file".into(),
    }
}

/// Parses a gmsh `.msh` file (4.1 or 2.2, ASCII or binary). See the [module docs](self).
pub fn read(bytes: &[u8], file: &Path) -> Result<Mesh, ParseError> {
    let header = sniff(bytes, file)?;
    if header.binary {
        return super::msh_binary::read(bytes, file, header);
    }
    let version = header.version;
    let mut lines = Lines::new(bytes, file)?;
    let mut st = State::default();
    // $MeshFormat, header line, $EndMeshFormat (sniff checked the first two).
    next_nonempty(&mut lines, "$MeshFormat")?;
    next_nonempty(&mut lines, "the format line")?;
    expect_end(&mut lines, "$EndMeshFormat")?;
    while let Some((ln, raw)) = lines.next_line() {
        let t = raw.trim();
        if t.is_empty() {
            continue;
        }
        match t {
            "$PhysicalNames" => read_physical_names(&mut lines, &mut st)?,
            "$Entities" if version == Version::V4 => read_entities(&mut lines, &mut st)?,
            "$PartitionedEntities" => {
                return Err(lines.error(
                    ln,
                    "partitioned meshes are not supported (their physical groups live on \
                     partition entities): save the mesh without partitions",
                ));
            }
            "$Nodes" => {
                if st.seen_nodes {
                    return Err(lines.error(ln, "a second $Nodes section; expected only one"));
                }
                st.seen_nodes = true;
                match version {
                    Version::V4 => read_nodes_v4(&mut lines, &mut st, bytes.len())?,
                    Version::V2 => read_nodes_v2(&mut lines, &mut st, bytes.len())?,
                }
            }
            "$Elements" => {
                if !st.seen_nodes {
                    return Err(lines.error(ln, "expected the $Nodes section before $Elements"));
                }
                if st.seen_elements {
                    return Err(lines.error(ln, "a second $Elements section; expected only one"));
                }
                st.seen_elements = true;
                match version {
                    Version::V4 => read_elements_v4(&mut lines, &mut st, bytes.len())?,
                    Version::V2 => read_elements_v2(&mut lines, &mut st, bytes.len())?,
                }
            }
            s if s.starts_with('$') && !s.starts_with("$End") => {
                let end = format!("$End{}", &s[1..]);
                loop {
                    match lines.next_line() {
                        Some((_, l)) if l.trim() == end => break,
                        Some(_) => {}
                        None => return Err(lines.eof_error(&format!("'{end}' closing {s}"))),
                    }
                }
            }
            s => {
                return Err(lines.error(
                    ln,
                    format!("expected a section header such as $Nodes, found '{}'", snippet(s)),
                ));
            }
        }
    }
    complete(st, file)
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

fn next_nonempty<'a>(
    lines: &mut Lines<'a>,
    expected: &str,
) -> Result<(usize, &'a str), ParseError> {
    loop {
        match lines.next_line() {
            Some((ln, l)) if !l.trim().is_empty() => return Ok((ln, l.trim())),
            Some(_) => {}
            None => return Err(lines.eof_error(expected)),
        }
    }
}

fn expect_end(lines: &mut Lines<'_>, end: &str) -> Result<(), ParseError> {
    let (ln, t) = next_nonempty(lines, end)?;
    if t != end {
        return Err(lines.error(ln, format!("expected '{end}', found '{}'", snippet(t))));
    }
    Ok(())
}

/// Parses the next whitespace-separated field of `f`.
fn field<T: std::str::FromStr>(
    lines: &Lines<'_>,
    ln: usize,
    f: &mut std::str::SplitAsciiWhitespace<'_>,
    what: &str,
) -> Result<T, ParseError> {
    match f.next() {
        Some(s) => parse_field(lines.file(), ln, s, what),
        None => Err(lines.error(ln, format!("expected {what}, found the end of the line"))),
    }
}

fn read_physical_names(lines: &mut Lines<'_>, st: &mut State) -> Result<(), ParseError> {
    let (ln, t) = next_nonempty(lines, "the number of physical names")?;
    let n: usize = parse_field(lines.file(), ln, t, "the number of physical names")?;
    for _ in 0..n {
        let (ln, t) = next_nonempty(lines, "a physical name line 'dim tag \"name\"'")?;
        let (key, name) = physical_name(t).map_err(|m| lines.error(ln, m))?;
        st.physical_names.insert(key, name);
    }
    expect_end(lines, "$EndPhysicalNames")
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

fn read_entities(lines: &mut Lines<'_>, st: &mut State) -> Result<(), ParseError> {
    let (ln, t) = next_nonempty(lines, "the entity counts")?;
    let mut f = t.split_ascii_whitespace();
    let mut counts = [0usize; 4];
    for c in &mut counts {
        *c = field(lines, ln, &mut f, "the number of points, curves, surfaces and volumes")?;
    }
    for (dim, &count) in counts.iter().enumerate() {
        for _ in 0..count {
            let (ln, t) = next_nonempty(lines, "an entity line")?;
            let mut f = t.split_ascii_whitespace();
            let tag: i64 = field(lines, ln, &mut f, "an entity tag")?;
            // Points: x y z; curves, surfaces, volumes: a bounding box.
            let coords = if dim == 0 { 3 } else { 6 };
            for _ in 0..coords {
                field::<f64>(lines, ln, &mut f, "a coordinate")?;
            }
            let np: usize = field(lines, ln, &mut f, "the number of physical tags")?;
            let mut tags = Vec::with_capacity(np.min(16));
            for _ in 0..np {
                tags.push(field::<i64>(lines, ln, &mut f, "a physical tag")?.abs());
            }
            st.entities.insert((dim as u8, tag), tags);
        }
    }
    expect_end(lines, "$EndEntities")
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

fn read_point(
    lines: &Lines<'_>,
    ln: usize,
    f: &mut std::str::SplitAsciiWhitespace<'_>,
) -> Result<Point3<f64>, ParseError> {
    let mut c = [0.0f64; 3];
    for ci in &mut c {
        *ci = field(lines, ln, f, "a coordinate (number)")?;
        if !ci.is_finite() {
            return Err(lines.error(ln, "expected a finite coordinate"));
        }
    }
    Ok(Point3::new(c[0], c[1], c[2]))
}

fn read_nodes_v2(lines: &mut Lines<'_>, st: &mut State, size: usize) -> Result<(), ParseError> {
    let (ln, t) = next_nonempty(lines, "the number of nodes")?;
    let n: usize = parse_field(lines.file(), ln, t, "the number of nodes")?;
    // "1 0 0 0\n"
    st.nodes.reserve(count(lines, ln, n, 8, size, "nodes")?);
    for _ in 0..n {
        let (ln, t) = next_nonempty(lines, "a node line 'tag x y z'")?;
        let mut f = t.split_ascii_whitespace();
        let id: u64 = field(lines, ln, &mut f, "a node tag (integer)")?;
        let p = read_point(lines, ln, &mut f)?;
        add_node(lines.file(), st, id, p, Location::Line(ln))?;
    }
    expect_end(lines, "$EndNodes")
}

fn read_nodes_v4(lines: &mut Lines<'_>, st: &mut State, size: usize) -> Result<(), ParseError> {
    let (ln, t) = next_nonempty(lines, "the node section header")?;
    let mut f = t.split_ascii_whitespace();
    let blocks: usize = field(lines, ln, &mut f, "the number of entity blocks")?;
    let n: usize = field(lines, ln, &mut f, "the number of nodes")?;
    // A tag line "1\n" and a coordinate line "0 0 0\n".
    st.nodes.reserve(count(lines, ln, n, 8, size, "nodes")?);
    // "0 1 0 0\n"
    count(lines, ln, blocks, 8, size, "node entity blocks")?;
    let mut tags: Vec<(u64, usize)> = Vec::new();
    for _ in 0..blocks {
        let (ln, t) = next_nonempty(lines, "a node block header 'dim tag parametric count'")?;
        let mut f = t.split_ascii_whitespace();
        let _dim: u8 = field(lines, ln, &mut f, "an entity dimension")?;
        let _entity: i64 = field(lines, ln, &mut f, "an entity tag")?;
        let _param: u8 = field(lines, ln, &mut f, "the parametric flag (0 or 1)")?;
        let n: usize = field(lines, ln, &mut f, "the number of nodes in the block")?;
        tags.clear();
        tags.reserve(count(lines, ln, n, 8, size, "nodes in the block")?);
        for _ in 0..n {
            let (ln, t) = next_nonempty(lines, "a node tag")?;
            tags.push((parse_field(lines.file(), ln, t, "a node tag (integer)")?, ln));
        }
        for &(id, tag_ln) in &tags {
            let (ln, t) = next_nonempty(lines, "node coordinates 'x y z'")?;
            let p = read_point(lines, ln, &mut t.split_ascii_whitespace())?;
            add_node(lines.file(), st, id, p, Location::Line(tag_ln))?;
        }
    }
    expect_end(lines, "$EndNodes")
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

fn read_elements_v2(lines: &mut Lines<'_>, st: &mut State, size: usize) -> Result<(), ParseError> {
    let (ln, t) = next_nonempty(lines, "the number of elements")?;
    let n: usize = parse_field(lines.file(), ln, t, "the number of elements")?;
    // "1 15 0 1\n"
    st.elements.reserve(count(lines, ln, n, 9, size, "elements")?);
    let mut idx: Vec<usize> = Vec::with_capacity(32);
    for _ in 0..n {
        let (ln, t) = next_nonempty(lines, "an element line 'tag type ntags tags… nodes…'")?;
        let mut f = t.split_ascii_whitespace();
        let id: u64 = field(lines, ln, &mut f, "an element tag (integer)")?;
        let ty: u32 = field(lines, ln, &mut f, "an element type (integer)")?;
        let ntags: usize = field(lines, ln, &mut f, "the number of tags")?;
        let mut physical = 0i64;
        for k in 0..ntags {
            let tag: i64 = field(lines, ln, &mut f, "an element tag value (integer)")?;
            if k == 0 {
                physical = tag.abs();
            }
        }
        let (dim, count, what) = element_type(ty).ok_or_else(|| {
            lines.error(
                ln,
                format!(
                    "unknown gmsh element type {ty}; expected tetrahedra (4), hexahedra (5) and \
                     optionally points, lines, triangles or quadrangles (15, 1, 2, 3)"
                ),
            )
        })?;
        if dim == 3 && ty != 4 && ty != 5 {
            return Err(lines.error(ln, unsupported_3d(ty, what)));
        }
        idx.clear();
        for s in f.by_ref() {
            let nid: u64 = parse_field(lines.file(), ln, s, "a node tag (integer)")?;
            idx.push(node_index(lines.file(), st, Location::Line(ln), id, nid)?);
        }
        if idx.len() != count {
            return Err(lines.error(
                ln,
                format!(
                    "element {id} of type {ty} ({what}) lists {} node tags, expected {count}",
                    idx.len()
                ),
            ));
        }
        if dim == 3 {
            let e = add_element(
                lines.file(),
                st,
                id,
                build_element(ty, &idx),
                Location::Line(ln),
                true,
            )?;
            if physical != 0 {
                st.groups.entry((3, physical)).or_default().elements.push(e);
            }
        } else if physical != 0 {
            st.groups.entry((dim, physical)).or_default().nodes.extend_from_slice(&idx);
        }
    }
    expect_end(lines, "$EndElements")
}

fn read_elements_v4(lines: &mut Lines<'_>, st: &mut State, size: usize) -> Result<(), ParseError> {
    let (ln, t) = next_nonempty(lines, "the element section header")?;
    let mut f = t.split_ascii_whitespace();
    let blocks: usize = field(lines, ln, &mut f, "the number of entity blocks")?;
    let n: usize = field(lines, ln, &mut f, "the number of elements")?;
    // "1 1\n"
    st.elements.reserve(count(lines, ln, n, 4, size, "elements")?);
    // "0 1 15 1\n"
    count(lines, ln, blocks, 9, size, "element entity blocks")?;
    let mut idx: Vec<usize> = Vec::with_capacity(32);
    for _ in 0..blocks {
        let (ln, t) = next_nonempty(lines, "an element block header 'dim tag type count'")?;
        let mut f = t.split_ascii_whitespace();
        let block_dim: u8 = field(lines, ln, &mut f, "an entity dimension (0 to 3)")?;
        let entity: i64 = field(lines, ln, &mut f, "an entity tag")?;
        let ty: u32 = field(lines, ln, &mut f, "an element type")?;
        let n: usize = field(lines, ln, &mut f, "the number of elements in the block")?;
        let n = count(lines, ln, n, 4, size, "elements in the block")?;
        if block_dim > 3 {
            return Err(lines.error(ln, format!("expected a dimension 0 to 3, found {block_dim}")));
        }
        let known = element_type(ty);
        let (dim, expected, what) = match known {
            Some((d, c, w)) => (d, Some(c), w),
            None => (block_dim, None, "unknown type"),
        };
        if dim != block_dim {
            return Err(lines.error(
                ln,
                format!("element type {ty} ({what}) is {dim}D but the block is {block_dim}D"),
            ));
        }
        if dim == 3 && ty != 4 && ty != 5 {
            return Err(lines.error(ln, unsupported_3d(ty, what)));
        }
        let first_element = st.elements.len();
        let first_node = st.lower_nodes.len();
        for _ in 0..n {
            let (ln, t) = next_nonempty(lines, "an element line 'tag node-tags…'")?;
            let mut f = t.split_ascii_whitespace();
            let id: u64 = field(lines, ln, &mut f, "an element tag (integer)")?;
            idx.clear();
            for s in f.by_ref() {
                let nid: u64 = parse_field(lines.file(), ln, s, "a node tag (integer)")?;
                idx.push(node_index(lines.file(), st, Location::Line(ln), id, nid)?);
            }
            if expected.is_some_and(|c| c != idx.len()) || idx.is_empty() {
                return Err(lines.error(
                    ln,
                    format!(
                        "element {id} of type {ty} ({what}) lists {} node tags, expected {}",
                        idx.len(),
                        expected.unwrap_or(1)
                    ),
                ));
            }
            if dim == 3 {
                add_element(
                    lines.file(),
                    st,
                    id,
                    build_element(ty, &idx),
                    Location::Line(ln),
                    false,
                )?;
            } else {
                st.lower_nodes.extend_from_slice(&idx);
            }
        }
        st.blocks.push(Block {
            dim,
            entity,
            elements: first_element..st.elements.len(),
            nodes: first_node..st.lower_nodes.len(),
        });
    }
    expect_end(lines, "$EndElements")
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
