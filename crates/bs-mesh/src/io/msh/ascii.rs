//! ASCII gmsh meshes (`$MeshFormat` file type 0), versions 4.1 and 2.2: the sections read
//! line by line into the shared [`State`], errors naming the line.

use std::path::Path;

use nalgebra::Point3;

use super::state::{
    Block, State, add_element, add_node, build_element, complete, element_type, node_index,
    physical_name, unsupported_3d,
};
use super::{Header, Version};
use crate::Mesh;
use crate::io::inp::snippet;
use crate::io::{Lines, Location, ParseError, parse_field};

/// Parses an ASCII `.msh` file whose `$MeshFormat` header `sniff` read.
pub(super) fn read(bytes: &[u8], file: &Path, header: Header) -> Result<Mesh, ParseError> {
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
