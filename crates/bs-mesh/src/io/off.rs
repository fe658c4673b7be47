//! Object File Format (OFF) triangle surfaces.
//!
//! Header `OFF` (any case, after an optional UTF-8 byte-order mark), then the counts `nv nf ne` (on the header line or the next non-comment
//! line), `nv` vertex lines `x y z` (extra values such as colours are ignored) and `nf` face
//! lines `n i1 … in` (0-based indices, optional colour after them). Faces with more than three
//! vertices are fan-triangulated. `#` starts a comment anywhere.

use std::io::{self, Write};
use std::path::Path;

use nalgebra::Point3;

use super::{Lines, ParseError, parse_field};
use crate::TriSurface;

/// The next non-blank line with comments removed.
fn content<'a>(lines: &mut Lines<'a>) -> Option<(usize, &'a str)> {
    while let Some((ln, l)) = lines.next_line() {
        let l = l.split('#').next().unwrap_or("").trim();
        if !l.is_empty() {
            return Some((ln, l));
        }
    }
    None
}

/// Parses an OFF file into a triangle surface.
pub fn read(bytes: &[u8], file: &Path) -> Result<TriSurface, ParseError> {
    let mut lines = Lines::new(bytes, file)?;
    let (ln, header) = content(&mut lines).ok_or_else(|| lines.eof_error("the 'OFF' header"))?;
    let rest = header
        .get(..3)
        .filter(|h| h.eq_ignore_ascii_case("OFF"))
        .map(|_| &header[3..])
        .ok_or_else(|| lines.error(ln, format!("expected the 'OFF' header, found '{header}'")))?;
    let (ln, counts) = if rest.trim().is_empty() {
        content(&mut lines).ok_or_else(|| lines.eof_error("the counts 'nv nf ne'"))?
    } else {
        (ln, rest)
    };
    let mut tok = counts.split_whitespace();
    let mut count = |what: &str| -> Result<usize, ParseError> {
        let f =
            tok.next().ok_or_else(|| lines.error(ln, format!("expected {what}, found nothing")))?;
        parse_field(file, ln, f, what)
    };
    let nv = count("the vertex count")?;
    let nf = count("the face count")?;
    // Each vertex line needs at least 6 bytes ("0 0 0\n"), each face 8: cap preallocation by
    // what the file can hold so that a corrupted count cannot allocate huge buffers (such a
    // count then fails at the end of the file, naming the count).
    let mut s = TriSurface {
        vertices: Vec::with_capacity(nv.min(bytes.len() / 6)),
        triangles: Vec::with_capacity(nf.min(bytes.len() / 8)),
    };
    for i in 0..nv {
        let (ln, l) =
            content(&mut lines).ok_or_else(|| lines.eof_error(&format!("vertex {i} of {nv}")))?;
        let mut tok = l.split_whitespace();
        let mut p = [0.0; 3];
        for (c, x) in p.iter_mut().enumerate() {
            let f = tok.next().ok_or_else(|| {
                lines.error(ln, format!("vertex {i} needs 3 coordinates, found {c}"))
            })?;
            *x = parse_field(file, ln, f, "a vertex coordinate")?;
        }
        s.vertices.push(Point3::new(p[0], p[1], p[2]));
    }
    let mut poly = Vec::new();
    for i in 0..nf {
        let (ln, l) =
            content(&mut lines).ok_or_else(|| lines.eof_error(&format!("face {i} of {nf}")))?;
        let mut tok = l.split_whitespace();
        let n: usize = parse_field(file, ln, tok.next().unwrap_or(""), "the face's vertex count")?;
        if n < 3 {
            return Err(
                lines.error(ln, format!("face {i} has {n} vertices; at least 3 are needed"))
            );
        }
        poly.clear();
        for k in 0..n {
            let f = tok.next().ok_or_else(|| {
                lines.error(ln, format!("face {i} declares {n} vertices but lists {k}"))
            })?;
            let v: usize = parse_field(file, ln, f, "a vertex index")?;
            if v >= nv {
                return Err(lines.error(
                    ln,
                    format!("face {i}: vertex index {v} is beyond the {nv} vertices (0-based)"),
                ));
            }
            poly.push(v);
        }
        for k in 1..n - 1 {
            s.triangles.push([poly[0], poly[k], poly[k + 1]]);
        }
    }
    Ok(s)
}

/// Writes an OFF file (round-trip-exact coordinates, triangles as `3 a b c`).
pub fn write(w: &mut dyn Write, s: &TriSurface) -> io::Result<()> {
    super::require_indices_in_range(s)?;
    let nv = s.vertices.len();
    writeln!(w, "OFF")?;
    writeln!(w, "{} {} 0", nv, s.triangles.len())?;
    for p in &s.vertices {
        writeln!(w, "{:?} {:?} {:?}", p.x, p.y, p.z)?;
    }
    for t in &s.triangles {
        writeln!(w, "3 {} {} {}", t[0], t[1], t[2])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::Location;

    #[test]
    fn counts_on_header_line_comments_and_quads() {
        let text =
            "OFF 4 1 0 # counts here\n# comment\n0 0 0\n1 0 0\n\n1 1 0 255 0 0\n0 1 0\n4 0 1 2 3\n";
        let s = read(text.as_bytes(), Path::new("a.off")).unwrap();
        assert_eq!(s.vertices.len(), 4);
        assert_eq!(s.vertices[2], Point3::new(1.0, 1.0, 0.0));
        assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn lower_case_header_and_byte_order_mark() {
        let p = Path::new("a.off");
        let text = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let expect = read(text.as_bytes(), p).unwrap();
        assert_eq!(expect.triangles, vec![[0, 1, 2]]);
        assert_eq!(read(text.to_ascii_lowercase().as_bytes(), p).unwrap(), expect);
        assert_eq!(read(b"Off 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", p).unwrap(), expect);
        let bom = [crate::io::UTF8_BOM, text.as_bytes()].concat();
        assert_eq!(read(&bom, p).unwrap(), expect);
        // Line numbers are unchanged by the mark.
        let bom = [crate::io::UTF8_BOM, b"OFF\n3 1 0\n0 0 0\n".as_slice()].concat();
        assert_eq!(read(&bom, p).unwrap_err().location, Location::Line(3));
    }

    #[test]
    fn errors_name_line() {
        let p = Path::new("a.off");
        let e = read(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", p).unwrap_err();
        assert_eq!(e.location, Location::Line(6));
        assert_eq!(e.message, "face 0: vertex index 3 is beyond the 3 vertices (0-based)");
        let e = read(b"OFF\n3 1 0\n0 0 0\n1 0 0\n", p).unwrap_err();
        assert_eq!(e.location, Location::Line(4));
        assert_eq!(e.message, "unexpected end of file: expected vertex 2 of 3");
        let e = read(b"PLY\n", p).unwrap_err();
        assert_eq!(e.message, "expected the 'OFF' header, found 'PLY'");
        // A corrupted huge count must not allocate: it fails at the end of the file.
        let e = read(b"OFF\n99999999999 1 0\n0 0 0\n", p).unwrap_err();
        assert_eq!(e.location, Location::Line(3));
    }
}
