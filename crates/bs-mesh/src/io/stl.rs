//! STL triangle surfaces, ASCII and binary.
//!
//! STL stores every facet with its own three vertices (a "triangle soup"). The reader merges
//! vertices with exactly equal coordinates (bitwise, with `-0.0 == 0.0`) into an indexed
//! [`TriSurface`], keeping the order of first appearance. Degenerate facets are kept:
//! validation reports them with their index.
//!
//! Format detection: a file whose size is exactly `84 + 50·n` where `n` is the little-endian
//! `u32` at byte 80 is binary, even when it starts with `solid` (many exporters write that
//! into the binary header). Otherwise a file starting with `solid` (after an optional UTF-8
//! byte-order mark and whitespace) is ASCII, and anything else is a (truncated or padded)
//! binary file, reported with its expected and actual size.
//!
//! ASCII keywords are case-insensitive (`SOLID`, `FACET NORMAL`, `VERTEX`, `ENDSOLID`…), as
//! several CAD exporters write them in capitals.

use std::collections::HashMap;
use std::io::{self, Write};
use std::path::Path;

use nalgebra::{Point3, Vector3};

use super::{Location, ParseError};
use crate::TriSurface;

/// Parses an ASCII or binary STL file into an indexed surface with merged vertices.
pub fn read(bytes: &[u8], file: &Path) -> Result<TriSurface, ParseError> {
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        if 84 + 50 * n == bytes.len() as u64 {
            return read_binary(bytes, file);
        }
    }
    let text = super::strip_bom(bytes);
    let start = text.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(text.len());
    let looks_ascii =
        text[start..].len() >= 5 && text[start..start + 5].eq_ignore_ascii_case(b"solid");
    if looks_ascii {
        match read_ascii(text, file) {
            Ok(s) => Ok(s),
            // A binary file whose header starts with "solid" but whose size is wrong: the
            // size message is the useful one.
            Err(e) if bytes.len() >= 84 && std::str::from_utf8(bytes).is_err() => {
                Err(binary_size_error(bytes, file).unwrap_or(e))
            }
            Err(e) => Err(e),
        }
    } else {
        match binary_size_error(bytes, file) {
            Some(e) => Err(e),
            None => read_binary(bytes, file),
        }
    }
}

fn binary_size_error(bytes: &[u8], file: &Path) -> Option<ParseError> {
    if bytes.len() < 84 {
        return Some(ParseError::new(
            file,
            Location::Byte(bytes.len()),
            format!(
                "file has {} bytes: too short for a binary STL (80-byte header and a 4-byte \
                 triangle count) and it does not start with 'solid' as an ASCII STL must",
                bytes.len()
            ),
        ));
    }
    let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
    let expected = 84 + 50 * n;
    (expected != bytes.len() as u64).then(|| {
        ParseError::new(
            file,
            Location::Byte(80),
            format!(
                "binary STL: expected {n} triangles (84+50·{n} = {expected} bytes), file has {} \
                 bytes; the file is truncated or not an STL file",
                bytes.len()
            ),
        )
    })
}

/// Merges exactly equal vertices into an indexed surface.
#[derive(Debug, Default)]
struct Merger {
    index: HashMap<[u64; 3], usize>,
    surface: TriSurface,
}

impl Merger {
    fn with_capacity(triangles: usize) -> Self {
        let mut m = Merger::default();
        m.surface.triangles.reserve(triangles);
        m.surface.vertices.reserve(triangles / 2 + 3);
        m
    }

    fn vertex(&mut self, p: [f64; 3]) -> usize {
        // `+ 0.0` maps -0.0 to 0.0 so that the two zeros merge.
        let key = [(p[0] + 0.0).to_bits(), (p[1] + 0.0).to_bits(), (p[2] + 0.0).to_bits()];
        let vertices = &mut self.surface.vertices;
        *self.index.entry(key).or_insert_with(|| {
            vertices.push(Point3::new(p[0], p[1], p[2]));
            vertices.len() - 1
        })
    }

    fn triangle(&mut self, t: [[f64; 3]; 3]) {
        let tri = [self.vertex(t[0]), self.vertex(t[1]), self.vertex(t[2])];
        self.surface.triangles.push(tri);
    }
}

fn read_binary(bytes: &[u8], file: &Path) -> Result<TriSurface, ParseError> {
    if let Some(e) = binary_size_error(bytes, file) {
        return Err(e);
    }
    let n = (bytes.len() - 84) / 50;
    let mut m = Merger::with_capacity(n);
    let f32_at =
        |o: usize| f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
    for t in 0..n {
        let base = 84 + 50 * t + 12; // skip the stored normal
        let mut tri = [[0.0; 3]; 3];
        for (v, p) in tri.iter_mut().enumerate() {
            for (c, x) in p.iter_mut().enumerate() {
                let o = base + 12 * v + 4 * c;
                let value = f32_at(o);
                if !value.is_finite() {
                    return Err(ParseError::new(
                        file,
                        Location::Byte(o),
                        format!("binary STL: triangle {t} has a non-finite coordinate ({value})"),
                    ));
                }
                *x = value as f64;
            }
        }
        m.triangle(tri);
    }
    Ok(m.surface)
}

/// The keywords of ASCII STL, matched case-insensitively.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Keyword {
    Solid,
    EndSolid,
    Facet,
    Outer,
    Vertex,
    EndLoop,
    EndFacet,
    Other,
}

fn keyword(token: &str) -> Keyword {
    const KEYWORDS: [(&str, Keyword); 7] = [
        ("solid", Keyword::Solid),
        ("endsolid", Keyword::EndSolid),
        ("facet", Keyword::Facet),
        ("outer", Keyword::Outer),
        ("vertex", Keyword::Vertex),
        ("endloop", Keyword::EndLoop),
        ("endfacet", Keyword::EndFacet),
    ];
    KEYWORDS.iter().find(|(k, _)| k.eq_ignore_ascii_case(token)).map_or(Keyword::Other, |k| k.1)
}

/// Parses ASCII STL text (`bytes` without its byte-order mark).
fn read_ascii(bytes: &[u8], file: &Path) -> Result<TriSurface, ParseError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        ParseError::new(
            file,
            Location::Byte(e.valid_up_to()),
            "ASCII STL is not valid text here (a binary STL must be exactly 84+50·N bytes)",
        )
    })?;
    let err = |line: usize, msg: String| ParseError::new(file, Location::Line(line), msg);
    let mut m = Merger::with_capacity((bytes.len() / 200).min(1 << 20));
    // States: outside a solid, inside a solid, inside a facet (collecting vertices).
    let mut in_solid = false;
    let mut facet: Option<(usize, Vec<[f64; 3]>)> = None;
    let mut seen_loop = false;
    for (i, line) in text.lines().enumerate() {
        let ln = i + 1;
        let mut tok = line.split_whitespace();
        let Some(key) = tok.next() else { continue };
        match (keyword(key), in_solid, facet.is_some()) {
            (Keyword::Solid, false, _) => in_solid = true,
            (Keyword::EndSolid, true, false) => in_solid = false,
            (Keyword::Facet, true, false) => {
                facet = Some((ln, Vec::with_capacity(3)));
                seen_loop = false;
            }
            (Keyword::Outer, true, true) if !seen_loop => seen_loop = true,
            (Keyword::Vertex, true, true) if seen_loop => {
                let mut p = [0.0; 3];
                for (c, x) in p.iter_mut().enumerate() {
                    let f = tok.next().ok_or_else(|| {
                        err(ln, format!("'vertex' needs 3 coordinates, found {c}"))
                    })?;
                    *x = super::parse_field(file, ln, f, "a vertex coordinate")?;
                }
                if let Some((_, v)) = facet.as_mut() {
                    v.push(p);
                }
            }
            (Keyword::EndLoop, true, true) => {}
            (Keyword::EndFacet, true, true) => {
                let (start, v) = facet.take().unwrap_or_default();
                if v.len() != 3 {
                    return Err(err(
                        start,
                        format!("facet has {} vertices; an STL facet has exactly 3", v.len()),
                    ));
                }
                m.triangle([v[0], v[1], v[2]]);
            }
            _ => {
                let expected = match (in_solid, facet.is_some()) {
                    (false, _) => "'solid'",
                    (true, false) => "'facet normal' or 'endsolid'",
                    (true, true) if !seen_loop => "'outer loop'",
                    (true, true) => "'vertex', 'endloop' or 'endfacet'",
                };
                return Err(err(ln, format!("expected {expected}, found '{}'", line.trim())));
            }
        }
    }
    if let Some((start, _)) = facet {
        return Err(err(start, "unexpected end of file inside this facet".into()));
    }
    Ok(m.surface)
}

fn unit_normal(s: &TriSurface, t: &[usize; 3]) -> Vector3<f64> {
    let [a, b, c] = [s.vertices[t[0]], s.vertices[t[1]], s.vertices[t[2]]];
    let n = (b - a).cross(&(c - a));
    let len = n.norm();
    if len > 0.0 && len.is_finite() { n / len } else { Vector3::zeros() }
}

/// Writes a binary STL (coordinates rounded to `f32`, which is all the format holds; normals
/// computed from the vertices).
///
/// Fails with [`io::ErrorKind::InvalidInput`] when a coordinate is beyond the `f32` range
/// (it would become infinite).
pub fn write_binary(w: &mut dyn Write, s: &TriSurface) -> io::Result<()> {
    super::require_indices_in_range(s)?;
    for t in &s.triangles {
        for &v in t {
            let p = s.vertices[v];
            if p.iter().any(|&x| x.is_finite() && !(x as f32).is_finite()) {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!(
                        "vertex {v} ({p}) is beyond the f32 range of binary STL; write ASCII STL, OFF or OBJ"
                    ),
                ));
            }
        }
    }
    let n = u32::try_from(s.triangles.len()).map_err(|_| {
        io::Error::new(io::ErrorKind::InvalidInput, "binary STL holds at most 2^32-1 triangles")
    })?;
    let mut header = [b' '; 80];
    let text = b"binary STL written by brainshift";
    header[..text.len()].copy_from_slice(text);
    w.write_all(&header)?;
    w.write_all(&n.to_le_bytes())?;
    let mut rec = [0u8; 50];
    for t in &s.triangles {
        let normal = unit_normal(s, t);
        let mut o = 0;
        let mut put = |x: f64, rec: &mut [u8; 50]| {
            rec[o..o + 4].copy_from_slice(&(x as f32).to_le_bytes());
            o += 4;
        };
        for c in 0..3 {
            put(normal[c], &mut rec);
        }
        for &v in t {
            for c in 0..3 {
                put(s.vertices[v][c], &mut rec);
            }
        }
        rec[48] = 0;
        rec[49] = 0;
        w.write_all(&rec)?;
    }
    Ok(())
}

/// Writes an ASCII STL with round-trip-exact `f64` coordinates.
pub fn write_ascii(w: &mut dyn Write, s: &TriSurface) -> io::Result<()> {
    super::require_indices_in_range(s)?;
    writeln!(w, "solid brainshift")?;
    for t in &s.triangles {
        let n = unit_normal(s, t);
        writeln!(w, "facet normal {:?} {:?} {:?}", n.x, n.y, n.z)?;
        writeln!(w, "  outer loop")?;
        for &v in t {
            let p = s.vertices[v];
            writeln!(w, "    vertex {:?} {:?} {:?}", p.x, p.y, p.z)?;
        }
        writeln!(w, "  endloop")?;
        writeln!(w, "endfacet")?;
    }
    writeln!(w, "endsolid brainshift")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("t.stl")
    }

    #[test]
    fn truncated_binary_names_sizes() {
        let mut b = vec![0u8; 84 + 50 * 2];
        b[80] = 2;
        b.truncate(84 + 50 + 7);
        let e = read(&b, p()).unwrap_err();
        assert_eq!(e.location, Location::Byte(80));
        assert!(e.message.contains("expected 2 triangles"), "{}", e.message);
        assert!(e.message.contains("file has 141 bytes"), "{}", e.message);
    }

    #[test]
    fn binary_starting_with_solid_is_binary() {
        let s = TriSurface {
            vertices: vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
            ],
            triangles: vec![[0, 1, 2]],
        };
        let mut b = Vec::new();
        write_binary(&mut b, &s).unwrap();
        b[..5].copy_from_slice(b"solid");
        assert_eq!(read(&b, p()).unwrap(), s);
    }

    #[test]
    fn ascii_errors_name_line() {
        let text = "solid x\nfacet normal 0 0 1\n outer loop\n vertex 0 0 0\n vertex 1 0 zz\n";
        let e = read(text.as_bytes(), p()).unwrap_err();
        assert_eq!(e.location, Location::Line(5));
        assert_eq!(e.message, "expected a vertex coordinate, found 'zz'");
        let text = "solid x\nfacet normal 0 0 1\n outer loop\n vertex 0 0 0\n endloop\nendfacet\n";
        let e = read(text.as_bytes(), p()).unwrap_err();
        assert_eq!(e.location, Location::Line(2));
        assert!(e.message.contains("facet has 1 vertices"), "{}", e.message);
        let e = read(b"solid x\nbogus\n", p()).unwrap_err();
        assert_eq!(e.location, Location::Line(2));
        assert!(e.message.contains("expected 'facet normal' or 'endsolid'"), "{}", e.message);
    }

    const UPPER: &str = "SOLID CAD\nFACET NORMAL 0 0 1\n OUTER LOOP\n  VERTEX 0 0 0\n  VERTEX 1 0 0\n  \
                         Vertex 0 1 0\n ENDLOOP\nENDFACET\nEndSolid CAD\n";

    #[test]
    fn ascii_keywords_are_case_insensitive() {
        let lower = UPPER.to_ascii_lowercase();
        let expect = read(lower.as_bytes(), p()).unwrap();
        assert_eq!(expect.triangles, vec![[0, 1, 2]]);
        assert_eq!(read(UPPER.as_bytes(), p()).unwrap(), expect);
    }

    #[test]
    fn ascii_with_byte_order_mark_is_ascii() {
        // Long enough (> 84 bytes) that the old reader took it for a truncated binary file.
        let mut b = crate::io::UTF8_BOM.to_vec();
        b.extend_from_slice(UPPER.as_bytes());
        assert!(b.len() > 84);
        let s = read(&b, p()).unwrap();
        assert_eq!(s, read(UPPER.as_bytes(), p()).unwrap());
        // Errors keep their line numbers.
        let mut b = crate::io::UTF8_BOM.to_vec();
        b.extend_from_slice(b"solid x\nbogus\n");
        assert_eq!(read(&b, p()).unwrap_err().location, Location::Line(2));
    }

    #[test]
    fn ascii_merges_equal_vertices_and_signed_zero() {
        let text = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n\
                    endloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\n\
                    vertex -0 1 0\nendloop\nendfacet\nendsolid x\n";
        let s = read(text.as_bytes(), p()).unwrap();
        assert_eq!(s.vertices.len(), 4);
        assert_eq!(s.triangles, vec![[0, 1, 2], [1, 3, 2]]);
    }
}
