//! POLYDATA: a 40-byte header (counts of points, and count and size *in bytes* of each cell
//! array: vertices, lines, polygons, triangle strips; the number of attributes), the points
//! (3 × float32 each), the four cell arrays (each cell a u32 count N then N u32 point
//! indices), then the attributes: a 6-byte header each (type, components, count), their
//! names NUL-terminated one after another (padded to an even length), and their float32
//! data. [`PolyData::triangles`] reads the surface as triangles: polygons fanned, strips
//! split with every other triangle flipped.

use super::bytes::{Reader, put_f32s, put_u32, u32_of};
use super::{Decode, Encode, Encoded, expect};
use crate::error::ContentError;
use crate::frame::Message;

/// A cell array: each cell its count then its point indices.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Cells {
    /// Number of cells.
    pub count: u32,
    /// The words (N, i₁ … i_N)*.
    pub words: Vec<u32>,
}

impl Cells {
    /// Cells from lists of point indices.
    pub fn of<'c>(cells: impl IntoIterator<Item = &'c [u32]>) -> Cells {
        let mut c = Cells::default();
        for cell in cells {
            c.count += 1;
            c.words.push(cell.len() as u32);
            c.words.extend_from_slice(cell);
        }
        c
    }

    /// Triangles, one cell each.
    pub fn triangles(t: &[[u32; 3]]) -> Cells {
        let mut words = Vec::with_capacity(4 * t.len());
        for tri in t {
            words.push(3);
            words.extend_from_slice(tri);
        }
        Cells { count: t.len() as u32, words }
    }

    /// The cells, in order (the words checked when read).
    pub fn iter(&self) -> impl Iterator<Item = &[u32]> {
        let mut at = 0usize;
        std::iter::from_fn(move || {
            let n = *self.words.get(at)? as usize;
            let cell = self.words.get(at + 1..at + 1 + n)?;
            at += 1 + n;
            Some(cell)
        })
    }
}

/// One attribute (point or cell data).
#[derive(Debug, Clone, PartialEq)]
pub struct Attribute {
    /// The type byte: 0x00–0x04 point scalars, vectors, normals, tensors, RGBA; 0x10–0x14
    /// the same for cells.
    pub kind: u8,
    /// Components per tuple.
    pub components: u8,
    /// Tuples.
    pub count: u32,
    /// Its name.
    pub name: String,
    /// `count × components` values.
    pub data: Vec<f32>,
}

/// A POLYDATA's content.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PolyData {
    /// Points.
    pub points: Vec<[f32; 3]>,
    /// Vertices.
    pub vertices: Cells,
    /// Lines.
    pub lines: Cells,
    /// Polygons.
    pub polygons: Cells,
    /// Triangle strips.
    pub strips: Cells,
    /// Attributes.
    pub attributes: Vec<Attribute>,
}

impl PolyData {
    /// The surface's triangles: polygons fanned from their first point, strips split (every
    /// other triangle flipped to keep the orientation).
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        for p in self.polygons.iter() {
            out.extend((1..p.len().saturating_sub(1)).map(|k| [p[0], p[k], p[k + 1]]));
        }
        for s in self.strips.iter() {
            out.extend((0..s.len().saturating_sub(2)).map(|k| {
                if k % 2 == 0 { [s[k], s[k + 1], s[k + 2]] } else { [s[k + 1], s[k], s[k + 2]] }
            }));
        }
        out
    }
}

/// Reads a cell array of `count` cells in `size` bytes, each index below `points`.
fn cells(
    r: &mut Reader<'_>,
    what: &str,
    count: u32,
    size: u32,
    points: u32,
) -> Result<Cells, ContentError> {
    if !size.is_multiple_of(4) {
        return Err(r.error(format!("{what}: {size} bytes is not a whole number of u32 words")));
    }
    let raw = r.take(size as usize, what)?;
    let words: Vec<u32> =
        raw.chunks_exact(4).map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]])).collect();
    let (mut at, mut n) = (0usize, 0u32);
    while at < words.len() {
        let len = words[at] as usize;
        let cell = words
            .get(at + 1..at + 1 + len)
            .ok_or_else(|| r.error(format!("{what}: cell {} runs past its array", n + 1)))?;
        if let Some(&i) = cell.iter().find(|&&i| i >= points) {
            return Err(
                r.error(format!("{what}: cell {} refers to point {i}, there are {points}", n + 1))
            );
        }
        at += 1 + len;
        n += 1;
    }
    if n != count {
        return Err(r.error(format!("{what}: the header says {count} cells, the array holds {n}")));
    }
    Ok(Cells { count, words })
}

/// Reads the attributes (headers, names, data).
fn attributes(r: &mut Reader<'_>, n: u32) -> Result<Vec<Attribute>, ContentError> {
    let mut heads = Vec::new();
    for _ in 0..n {
        let kind = r.u8("an attribute's type")?;
        let components = r.u8("an attribute's components")?;
        heads.push((kind, components, r.u32("an attribute's count")?));
    }
    let mut names = Vec::new();
    let mut name_bytes = 0usize;
    for k in 0..n {
        let rest = &r.data[r.at..];
        let end = rest.iter().position(|&b| b == 0).ok_or_else(|| {
            r.error(format!("attribute {}'s name does not end with a NUL", k + 1))
        })?;
        names.push(crate::name::read_field(r.take(end + 1, "an attribute name")?));
        name_bytes += end + 1;
    }
    if name_bytes % 2 == 1 {
        r.take(1, "the names' padding")?;
    }
    let mut out = Vec::with_capacity(heads.len());
    for ((kind, components, count), name) in heads.into_iter().zip(names) {
        let values = count as usize * components as usize;
        let raw = r.take(values.saturating_mul(4), "an attribute's data")?;
        let data =
            raw.chunks_exact(4).map(|b| f32::from_be_bytes([b[0], b[1], b[2], b[3]])).collect();
        out.push(Attribute { kind, components, count, name, data });
    }
    Ok(out)
}

impl Decode for PolyData {
    fn decode(m: &Message) -> Result<PolyData, ContentError> {
        expect(m, "POLYDATA")?;
        let mut r = Reader::new("POLYDATA", m.content());
        let mut h = [0u32; 10];
        for x in &mut h {
            *x = r.u32("the 40-byte POLYDATA header")?;
        }
        let [np, nv, sv, nl, sl, npoly, spoly, ns, ss, na] = h;
        let raw = r.take((np as usize).saturating_mul(12), "the points")?;
        let points = raw
            .chunks_exact(12)
            .map(|b| {
                std::array::from_fn(|k| f32::from_be_bytes(std::array::from_fn(|j| b[4 * k + j])))
            })
            .collect();
        let vertices = cells(&mut r, "vertices", nv, sv, np)?;
        let lines = cells(&mut r, "lines", nl, sl, np)?;
        let polygons = cells(&mut r, "polygons", npoly, spoly, np)?;
        let strips = cells(&mut r, "triangle strips", ns, ss, np)?;
        let attributes = attributes(&mut r, na)?;
        r.finish()?;
        Ok(PolyData { points, vertices, lines, polygons, strips, attributes })
    }
}

impl Encode for PolyData {
    fn kind(&self) -> String {
        "POLYDATA".into()
    }

    fn encode(&self) -> Result<Encoded<'_>, ContentError> {
        let arrays = [&self.vertices, &self.lines, &self.polygons, &self.strips];
        let mut out = Vec::new();
        put_u32(&mut out, u32_of(self.points.len(), "points")?);
        for c in arrays {
            put_u32(&mut out, c.count);
            put_u32(&mut out, u32_of(4 * c.words.len(), "a cell array's bytes")?);
        }
        put_u32(&mut out, u32_of(self.attributes.len(), "attributes")?);
        for p in &self.points {
            put_f32s(&mut out, p);
        }
        for c in arrays {
            c.words.iter().for_each(|&w| put_u32(&mut out, w));
        }
        for a in &self.attributes {
            out.extend_from_slice(&[a.kind, a.components]);
            put_u32(&mut out, a.count);
        }
        let mut name_bytes = 0;
        for a in &self.attributes {
            if a.name.contains('\0') {
                return Err(ContentError::Pack(format!("attribute name {:?} holds a NUL", a.name)));
            }
            out.extend_from_slice(a.name.as_bytes());
            out.push(0);
            name_bytes += a.name.len() + 1;
        }
        if name_bytes % 2 == 1 {
            out.push(0);
        }
        for a in &self.attributes {
            if a.data.len() != a.count as usize * a.components as usize {
                return Err(ContentError::Pack(format!(
                    "attribute {:?}: {} values for {} tuples of {}",
                    a.name,
                    a.data.len(),
                    a.count,
                    a.components
                )));
            }
            put_f32s(&mut out, &a.data);
        }
        Ok(Encoded::owned(out))
    }
}
