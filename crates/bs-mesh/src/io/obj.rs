//! Wavefront OBJ triangle surfaces.
//!
//! Reads `v x y z [w]` vertex lines and `f` face lines whose entries may be `i`, `i/t`,
//! `i//n` or `i/t/n`, with 1-based or negative (relative to the vertices read so far)
//! indices. Polygons are fan-triangulated from their first vertex. Every other statement
//! (`vn`, `vt`, `g`, `o`, `s`, `usemtl`, `mtllib`, comments…) is ignored. Statement
//! keywords are case-insensitive and a leading UTF-8 byte-order mark is skipped.

use std::io::{self, Write};
use std::path::Path;

use nalgebra::Point3;

use super::{Lines, ParseError, parse_field};
use crate::TriSurface;

/// Parses an OBJ file into a triangle surface.
pub fn read(bytes: &[u8], file: &Path) -> Result<TriSurface, ParseError> {
    let mut lines = Lines::new(bytes, file)?;
    let mut s = TriSurface::default();
    // Positive indices may only be checked once all vertices are known (OBJ allows a face
    // before its vertices); remember the line of each face's first triangle.
    let mut face_lines: Vec<(usize, usize)> = Vec::new(); // (first triangle, line)
    let mut poly: Vec<usize> = Vec::new();
    while let Some((ln, line)) = lines.next_line() {
        let line = line.split('#').next().unwrap_or("");
        let mut tok = line.split_whitespace();
        // Statements are case-insensitive (`V`, `F` from some exporters).
        match tok.next().map(|k| k.to_ascii_lowercase()).as_deref() {
            Some("v") => {
                let mut p = [0.0; 3];
                for (c, x) in p.iter_mut().enumerate() {
                    let f = tok.next().ok_or_else(|| {
                        lines.error(ln, format!("'v' needs 3 coordinates, found {c}"))
                    })?;
                    *x = parse_field(file, ln, f, "a vertex coordinate")?;
                }
                s.vertices.push(Point3::new(p[0], p[1], p[2]));
            }
            Some("f") => {
                poly.clear();
                for entry in tok {
                    let idx = entry.split('/').next().unwrap_or("");
                    let i: i64 = parse_field(file, ln, idx, "a vertex index")?;
                    let n = s.vertices.len() as i64;
                    let index = match i {
                        0 => return Err(lines.error(ln, "vertex index 0: OBJ indices start at 1")),
                        i if i > 0 => i - 1,
                        i if i >= -n => n + i,
                        i => {
                            return Err(lines.error(
                                ln,
                                format!("relative vertex index {i} but only {n} vertices so far"),
                            ));
                        }
                    };
                    poly.push(index as usize);
                }
                if poly.len() < 3 {
                    return Err(lines.error(
                        ln,
                        format!("face has {} vertices; at least 3 are needed", poly.len()),
                    ));
                }
                face_lines.push((s.triangles.len(), ln));
                for k in 1..poly.len() - 1 {
                    s.triangles.push([poly[0], poly[k], poly[k + 1]]);
                }
            }
            _ => {}
        }
    }
    let nv = s.vertices.len();
    if let Some(t) = s.triangles.iter().position(|t| t.iter().any(|&i| i >= nv)) {
        let k = face_lines.partition_point(|&(first, _)| first <= t);
        let ln = face_lines[k.saturating_sub(1)].1;
        let bad = s.triangles[t].iter().copied().find(|&i| i >= nv).unwrap_or(0);
        return Err(lines.error(
            ln,
            format!("vertex index {} is beyond the {nv} vertices of the file", bad + 1),
        ));
    }
    Ok(s)
}

/// Writes `v` and `f` lines (1-based indices, round-trip-exact coordinates).
pub fn write(w: &mut dyn Write, s: &TriSurface) -> io::Result<()> {
    super::require_indices_in_range(s)?;
    let nv = s.vertices.len();
    writeln!(w, "# written by brainshift: {} vertices, {} triangles", nv, s.triangles.len())?;
    for p in &s.vertices {
        writeln!(w, "v {:?} {:?} {:?}", p.x, p.y, p.z)?;
    }
    for t in &s.triangles {
        writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::Location;

    #[test]
    fn forms_negative_indices_and_fans() {
        let text = "o thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n\
                    f 1/1/1 2//1 3/1 4\nf -4 -3 -2\n";
        let s = read(text.as_bytes(), Path::new("a.obj")).unwrap();
        assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2]]);
    }

    #[test]
    fn upper_case_statements_and_byte_order_mark() {
        let p = Path::new("a.obj");
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let expect = read(text.as_bytes(), p).unwrap();
        assert_eq!(expect.triangles, vec![[0, 1, 2]]);
        assert_eq!(read(text.to_ascii_uppercase().as_bytes(), p).unwrap(), expect);
        let bom = [crate::io::UTF8_BOM, text.as_bytes()].concat();
        assert_eq!(read(&bom, p).unwrap(), expect);
    }

    #[test]
    fn errors_name_line() {
        let p = Path::new("a.obj");
        let e = read(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", p).unwrap_err();
        assert_eq!(e.location, Location::Line(4));
        assert_eq!(e.message, "expected a vertex index, found 'x'");
        let e = read(b"v 0 0 0\nv 1 0 0\nf 1 2 5\nv 0 1 0\n", p).unwrap_err();
        assert_eq!(e.location, Location::Line(3));
        assert_eq!(e.message, "vertex index 5 is beyond the 3 vertices of the file");
        let e = read(b"v 0 0 0\nf -1 -2 -3\n", p).unwrap_err();
        assert_eq!(e.location, Location::Line(2));
        let e = read(b"v 0 0\n", p).unwrap_err();
        assert_eq!(e.message, "'v' needs 3 coordinates, found 2");
    }
}
