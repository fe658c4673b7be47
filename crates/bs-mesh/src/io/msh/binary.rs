//! Binary gmsh meshes (`$MeshFormat` file type 1), versions 4.1 and 2.2.
//!
//! Section headers (`$Nodes`, `$EndNodes`, …), counts in 2.2 and `$PhysicalNames` are text
//! lines; node and element data (and 4.1 `$Entities`) are raw numbers in the byte order given
//! by the integer `1` that follows the format line. In 4.1 counts and tags are `size_t` of
//! the header's data-size (4 or 8 bytes) and dimensions, entity tags and types are 32-bit
//! ints; in 2.2 tags and types are 32-bit ints. Coordinates are 64-bit floats.
//!
//! The sections are turned into the same [`State`] as the ASCII reader's, so a binary file
//! and the ASCII file of the same mesh give identical meshes and sets. Every count is checked
//! against the bytes left in the file before anything is reserved or looped over, and every
//! read is bounds-checked: errors name the byte offset and what was expected.

use std::path::Path;

use nalgebra::Point3;

use super::state::{
    Block, State, add_element, add_node, build_element, complete, element_type, node_index,
    physical_name, unsupported_3d,
};
use super::{Header, Version};
use crate::Mesh;
use crate::io::inp::snippet;
use crate::io::{Location, ParseError};

/// Byte cursor over a binary `.msh` file.
struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
    file: &'a Path,
    /// Bytes of a 4.1 `size_t` (4 or 8).
    size_t: usize,
    big_endian: bool,
}

impl<'a> Cursor<'a> {
    fn err(&self, at: usize, msg: impl Into<String>) -> ParseError {
        ParseError::new(self.file, Location::Byte(at), msg)
    }

    fn remaining(&self) -> usize {
        self.b.len() - self.pos
    }

    /// The next `n` raw bytes.
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], ParseError> {
        if n > self.remaining() {
            return Err(self.err(
                self.pos,
                format!(
                    "unexpected end of file: expected {what} ({n} bytes), only {} bytes remain; \
                     the file is truncated",
                    self.remaining()
                ),
            ));
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    /// An unsigned integer of `n` (4 or 8) bytes in the file's byte order.
    fn uint(&mut self, n: usize, what: &str) -> Result<u64, ParseError> {
        let raw = self.take(n, what)?;
        let mut a = [0u8; 8];
        if self.big_endian {
            a[8 - n..].copy_from_slice(raw);
            Ok(u64::from_be_bytes(a))
        } else {
            a[..n].copy_from_slice(raw);
            Ok(u64::from_le_bytes(a))
        }
    }

    /// A 32-bit signed int.
    fn int(&mut self, what: &str) -> Result<i64, ParseError> {
        Ok(self.uint(4, what)? as u32 as i32 as i64)
    }

    /// A 2.2 node or element tag: a 32-bit int that must not be negative.
    fn tag(&mut self, what: &str) -> Result<u64, ParseError> {
        let at = self.pos;
        let id = self.int(what)?;
        u64::try_from(id).map_err(|_| self.err(at, format!("expected {what} >= 0, found {id}")))
    }

    /// A 4.1 `size_t`.
    fn size(&mut self, what: &str) -> Result<u64, ParseError> {
        self.uint(self.size_t, what)
    }

    /// A finite 64-bit float.
    fn coordinate(&mut self) -> Result<f64, ParseError> {
        let at = self.pos;
        let x = f64::from_bits(self.uint(8, "a coordinate (8-byte float)")?);
        if !x.is_finite() {
            return Err(self.err(at, format!("expected a finite coordinate, found {x}")));
        }
        Ok(x)
    }

    fn point(&mut self) -> Result<Point3<f64>, ParseError> {
        Ok(Point3::new(self.coordinate()?, self.coordinate()?, self.coordinate()?))
    }

    /// A count of items of at least `item_bytes` bytes each, refused when the rest of the
    /// file cannot hold that many (a corrupt count never drives an allocation or a long loop).
    fn count(&self, n: u64, item_bytes: usize, at: usize, what: &str) -> Result<usize, ParseError> {
        let need = (n as u128) * (item_bytes as u128);
        if need > self.remaining() as u128 {
            return Err(self.err(
                at,
                format!(
                    "the file declares {n} {what} ({need} bytes at least) but only {} bytes \
                     remain; the file is truncated or corrupt",
                    self.remaining()
                ),
            ));
        }
        // `need` fits in the file, so `n` fits in usize.
        Ok(n as usize)
    }

    /// The next non-blank text line, trimmed, with its start offset.
    fn line(&mut self, what: &str) -> Result<(usize, &'a str), ParseError> {
        loop {
            if self.pos >= self.b.len() {
                return Err(self.err(self.pos, format!("unexpected end of file: expected {what}")));
            }
            let start = self.pos;
            let rest = &self.b[start..];
            let end = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
            self.pos = (start + end + 1).min(self.b.len());
            let text = std::str::from_utf8(&rest[..end])
                .map_err(|_| self.err(start, format!("expected {what} as a text line")))?
                .trim();
            if !text.is_empty() {
                return Ok((start, text));
            }
        }
    }

    /// A text line holding one count (2.2 `$Nodes` and `$Elements`, `$PhysicalNames`).
    fn count_line(&mut self, what: &str) -> Result<(usize, u64), ParseError> {
        let (at, t) = self.line(what)?;
        let n = t.parse().map_err(|_| {
            self.err(at, format!("expected {what} (an integer), found '{}'", snippet(t)))
        })?;
        Ok((at, n))
    }

    /// The closing line of a section.
    fn expect_end(&mut self, end: &str) -> Result<(), ParseError> {
        let (at, t) = self.line(end)?;
        if t != end {
            return Err(self.err(
                at,
                format!(
                    "expected '{end}', found '{}': the binary data before it has another \
                     length than its counts say (corrupt or truncated file)",
                    snippet(t)
                ),
            ));
        }
        Ok(())
    }
}

/// Reads a binary `.msh` file whose `$MeshFormat` line was parsed into `header`.
pub(super) fn read(bytes: &[u8], file: &Path, header: Header) -> Result<Mesh, ParseError> {
    let mut c =
        Cursor { b: bytes, pos: header.end, file, size_t: header.data_size, big_endian: false };
    byte_order(&mut c)?;
    c.expect_end("$EndMeshFormat")?;
    let mut st = State::default();
    while c.pos < c.b.len() {
        if c.b[c.pos..].iter().all(u8::is_ascii_whitespace) {
            break;
        }
        let (at, t) = c.line("a section header such as $Nodes")?;
        section(&mut c, &mut st, header.version, at, t)?;
    }
    complete(st, file)
}

/// The integer 1 after the format line tells the byte order.
fn byte_order(c: &mut Cursor<'_>) -> Result<(), ParseError> {
    let at = c.pos;
    let raw = c.take(4, "the byte-order integer 1")?;
    c.big_endian = match raw {
        [1, 0, 0, 0] => false,
        [0, 0, 0, 1] => true,
        _ => {
            return Err(c.err(
                at,
                format!(
                    "expected the integer 1 (4 bytes) after the binary format line, found \
                     {raw:02x?}; the file is corrupt (or was transferred as text)"
                ),
            ));
        }
    };
    Ok(())
}

/// Reads one section whose header line `t` started at `at`.
fn section(
    c: &mut Cursor<'_>,
    st: &mut State,
    version: Version,
    at: usize,
    t: &str,
) -> Result<(), ParseError> {
    match t {
        "$PhysicalNames" => physical_names(c, st),
        "$Entities" if version == Version::V4 => entities(c, st),
        "$PartitionedEntities" => Err(c.err(
            at,
            "partitioned meshes are not supported (their physical groups live on partition \
             entities): save the mesh without partitions",
        )),
        "$Nodes" => {
            if st.seen_nodes {
                return Err(c.err(at, "a second $Nodes section; expected only one"));
            }
            st.seen_nodes = true;
            match version {
                Version::V4 => nodes_v4(c, st)?,
                Version::V2 => nodes_v2(c, st)?,
            }
            c.expect_end("$EndNodes")
        }
        "$Elements" => {
            if !st.seen_nodes {
                return Err(c.err(at, "expected the $Nodes section before $Elements"));
            }
            if st.seen_elements {
                return Err(c.err(at, "a second $Elements section; expected only one"));
            }
            st.seen_elements = true;
            match version {
                Version::V4 => elements_v4(c, st)?,
                Version::V2 => elements_v2(c, st)?,
            }
            c.expect_end("$EndElements")
        }
        s if s.starts_with('$') && !s.starts_with("$End") => skip_section(c, s),
        s => Err(
            c.err(at, format!("expected a section header such as $Nodes, found '{}'", snippet(s)))
        ),
    }
}

/// Skips a section brainshift does not use (its body may be binary) up to its `$End…` line.
fn skip_section(c: &mut Cursor<'_>, s: &str) -> Result<(), ParseError> {
    let end = format!("\n$End{}", &s[1..]);
    let rest = &c.b[c.pos..];
    match rest.windows(end.len()).position(|w| w == end.as_bytes()) {
        Some(i) => {
            c.pos += i + 1;
            c.line("the end of the section").map(|_| ())
        }
        None => Err(c.err(c.b.len(), format!("unexpected end of file: expected '{}'", &end[1..]))),
    }
}

fn physical_names(c: &mut Cursor<'_>, st: &mut State) -> Result<(), ParseError> {
    let (at, n) = c.count_line("the number of physical names")?;
    // Each name line takes at least 6 bytes (`0 1 ""` and a newline).
    let n = c.count(n, 6, at, "physical names")?;
    for _ in 0..n {
        let (at, t) = c.line("a physical name line 'dim tag \"name\"'")?;
        let (key, name) = physical_name(t).map_err(|m| c.err(at, m))?;
        st.physical_names.insert(key, name);
    }
    c.expect_end("$EndPhysicalNames")
}

/// 4.1 `$Entities`: the physical tags of each point, curve, surface and volume.
fn entities(c: &mut Cursor<'_>, st: &mut State) -> Result<(), ParseError> {
    let mut counts = [0u64; 4];
    for n in &mut counts {
        *n = c.size("the number of points, curves, surfaces and volumes")?;
    }
    for (dim, &n) in counts.iter().enumerate() {
        // A point is at least a tag, 3 doubles and a size_t; other entities more.
        let n = c.count(n, 4 + 24 + c.size_t, c.pos, "entities")?;
        for _ in 0..n {
            let tag = c.int("an entity tag")?;
            let coords = if dim == 0 { 3 } else { 6 };
            c.take(8 * coords, "the entity's coordinates")?;
            let at = c.pos;
            let np = c.size("the number of physical tags")?;
            let np = c.count(np, 4, at, "physical tags")?;
            let mut tags = Vec::with_capacity(np);
            for _ in 0..np {
                tags.push(c.int("a physical tag")?.abs());
            }
            if dim > 0 {
                let at = c.pos;
                let nb = c.size("the number of bounding entities")?;
                let nb = c.count(nb, 4, at, "bounding entities")?;
                c.take(4 * nb, "the bounding entity tags")?;
            }
            st.entities.insert((dim as u8, tag), tags);
        }
    }
    c.expect_end("$EndEntities")
}

/// 2.2 `$Nodes`: a count line, then `int tag, 3 doubles` per node.
fn nodes_v2(c: &mut Cursor<'_>, st: &mut State) -> Result<(), ParseError> {
    let (at, n) = c.count_line("the number of nodes")?;
    let n = c.count(n, 4 + 24, at, "nodes")?;
    st.nodes.reserve(n);
    for _ in 0..n {
        let at = c.pos;
        let id = c.tag("a node tag")?;
        let p = c.point()?;
        add_node(c.file, st, id, p, Location::Byte(at))?;
    }
    Ok(())
}

/// 4.1 `$Nodes`: per entity block, all node tags then all coordinates.
fn nodes_v4(c: &mut Cursor<'_>, st: &mut State) -> Result<(), ParseError> {
    let at = c.pos;
    let blocks = c.size("the number of entity blocks")?;
    let n = c.size("the number of nodes")?;
    c.size("the minimum node tag")?;
    c.size("the maximum node tag")?;
    // A block header is 3 ints and a size_t; a node is a tag and 3 doubles.
    let blocks = c.count(blocks, 12 + c.size_t, at, "node entity blocks")?;
    st.nodes.reserve(c.count(n, c.size_t + 24, at, "nodes")?);
    for _ in 0..blocks {
        let dim = c.int("an entity dimension")?;
        c.int("an entity tag")?;
        let parametric = c.int("the parametric flag")?;
        let at = c.pos;
        let count = c.size("the number of nodes in the block")?;
        // Parametric nodes carry `dim` more coordinates.
        let extra = if parametric != 0 { dim.clamp(0, 3) as usize } else { 0 };
        let count = c.count(count, c.size_t + 8 * (3 + extra), at, "nodes in the block")?;
        // `count` fits in the file, so this allocation is bounded by its size.
        let mut tags = Vec::with_capacity(count);
        for _ in 0..count {
            tags.push((c.pos, c.size("a node tag")?));
        }
        for (at, id) in tags {
            let p = c.point()?;
            c.take(8 * extra, "the parametric coordinates")?;
            add_node(c.file, st, id, p, Location::Byte(at))?;
        }
    }
    Ok(())
}

/// Adds a tet/hex element defined at byte `at`; returns its index.
fn place(
    c: &Cursor<'_>,
    st: &mut State,
    (ty, id): (u32, u64),
    idx: &[usize],
    at: usize,
    allow_repeat: bool,
) -> Result<usize, ParseError> {
    add_element(c.file, st, id, build_element(ty, idx), Location::Byte(at), allow_repeat)
}

/// The node count and dimension of element type `ty`, refusing unknown and unsupported 3D
/// types (a binary file cannot be read past an element whose size is unknown).
fn known_type(c: &Cursor<'_>, ty: i64, at: usize) -> Result<(u8, usize, u32), ParseError> {
    let t = u32::try_from(ty).ok();
    let (dim, nodes, what) = t.and_then(element_type).ok_or_else(|| {
        c.err(
            at,
            format!(
                "unknown gmsh element type {ty}; expected tetrahedra (4), hexahedra (5) and \
                 optionally points, lines, triangles or quadrangles (15, 1, 2, 3)"
            ),
        )
    })?;
    let t = t.unwrap_or(0);
    if dim == 3 && t != 4 && t != 5 {
        return Err(c.err(at, unsupported_3d(t, what)));
    }
    Ok((dim, nodes, t))
}

/// 2.2 `$Elements`: a count line, then blocks `type, count, ntags` of elements
/// `tag, tags…, nodes…` (all 32-bit ints).
fn elements_v2(c: &mut Cursor<'_>, st: &mut State) -> Result<(), ParseError> {
    let (at, n) = c.count_line("the number of elements")?;
    // The smallest element (a point without tags) is 2 ints.
    let n = c.count(n, 8, at, "elements")?;
    st.elements.reserve(n);
    let mut idx = Vec::with_capacity(32);
    let mut read = 0;
    while read < n {
        let at = c.pos;
        let (dim, nodes, ty) = {
            let ty = c.int("an element type")?;
            known_type(c, ty, at)?
        };
        let follow = c.int("the number of elements that follow")?;
        let ntags = c.int("the number of tags")?;
        let ntags = usize::try_from(ntags)
            .map_err(|_| c.err(at, format!("expected a tag count >= 0, found {ntags}")))?;
        let item = 4 * (1 + ntags as u128 + nodes as u128);
        let follow = u64::try_from(follow).ok().filter(|&f| f as usize <= n - read);
        let follow = follow.ok_or_else(|| {
            c.err(at, format!("an element block header claims more than the {n} elements declared"))
        })?;
        let follow = c.count(follow, item.min(usize::MAX as u128) as usize, at, "elements")?;
        for _ in 0..follow {
            let at = c.pos;
            let id = c.tag("an element tag")?;
            let mut physical = 0;
            for k in 0..ntags {
                let tag = c.int("an element tag value")?;
                if k == 0 {
                    physical = tag.abs();
                }
            }
            idx.clear();
            for _ in 0..nodes {
                let nid = c.tag("a node tag")?;
                idx.push(node_index(c.file, st, Location::Byte(at), id, nid)?);
            }
            if dim == 3 {
                let e = place(c, st, (ty, id), &idx, at, true)?;
                if physical != 0 {
                    st.groups.entry((3, physical)).or_default().elements.push(e);
                }
            } else if physical != 0 {
                st.groups.entry((dim, physical)).or_default().nodes.extend_from_slice(&idx);
            }
        }
        read += follow;
    }
    Ok(())
}

/// 4.1 `$Elements`: per entity block `dim, entity, type` (ints) and a count, then per element
/// its tag and node tags (`size_t`).
fn elements_v4(c: &mut Cursor<'_>, st: &mut State) -> Result<(), ParseError> {
    let at = c.pos;
    let blocks = c.size("the number of entity blocks")?;
    let n = c.size("the number of elements")?;
    c.size("the minimum element tag")?;
    c.size("the maximum element tag")?;
    let blocks = c.count(blocks, 12 + c.size_t, at, "element entity blocks")?;
    st.elements.reserve(c.count(n, 2 * c.size_t, at, "elements")?);
    let mut idx = Vec::with_capacity(32);
    for _ in 0..blocks {
        let at = c.pos;
        let block_dim = c.int("an entity dimension")?;
        let entity = c.int("an entity tag")?;
        let (dim, nodes, ty) = {
            let ty = c.int("an element type")?;
            known_type(c, ty, at)?
        };
        if i64::from(dim) != block_dim {
            return Err(
                c.err(at, format!("element type {ty} is {dim}D but the block is {block_dim}D"))
            );
        }
        let count_at = c.pos;
        let count = c.size("the number of elements in the block")?;
        let count = c.count(count, c.size_t * (1 + nodes), count_at, "elements in the block")?;
        let first_element = st.elements.len();
        let first_node = st.lower_nodes.len();
        for _ in 0..count {
            let at = c.pos;
            let id = c.size("an element tag")?;
            idx.clear();
            for _ in 0..nodes {
                let nid = c.size("a node tag")?;
                idx.push(node_index(c.file, st, Location::Byte(at), id, nid)?);
            }
            if dim == 3 {
                place(c, st, (ty, id), &idx, at, false)?;
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
    Ok(())
}
