//! PLY (Stanford polygon format) vertices: what laser range scanners, stereo cameras and
//! Open3D or MeshLab write point clouds as.
//!
//! Reader: `ascii`, `binary_little_endian` and `binary_big_endian` 1.0; the `vertex`
//! element's `x`, `y`, `z` properties of any scalar type (other properties, such as colours
//! and normals, and other elements, such as faces, are skipped, list properties included).
//! Counts are checked against the bytes left before anything is allocated. The writer
//! (ASCII, for tests and fixtures) writes vertices only.

use std::io::{self, Write};
use std::path::Path;

use nalgebra::Point3;

use super::{Location, ParseError};

/// A scalar type of the format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// The value of `b` (`size()` bytes).
    fn decode(self, b: &[u8], little: bool) -> f64 {
        macro_rules! num {
            ($t:ty) => {{
                let a = b.try_into().expect("sized by the caller");
                if little { <$t>::from_le_bytes(a) as f64 } else { <$t>::from_be_bytes(a) as f64 }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => num!(i16),
            Scalar::U16 => num!(u16),
            Scalar::I32 => num!(i32),
            Scalar::U32 => num!(u32),
            Scalar::F32 => num!(f32),
            Scalar::F64 => num!(f64),
        }
    }
}

/// A property: a scalar, or a list (count type, item type).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Property {
    Scalar(Scalar),
    List(Scalar, Scalar),
}

/// An element declared in the header.
#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<(String, Property)>,
    line: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Binary { little: bool },
}

/// The header: encoding, elements, and the byte offset where the data start.
fn header(bytes: &[u8], file: &Path) -> Result<(Encoding, Vec<Element>, usize), ParseError> {
    let err = |line: usize, m: String| ParseError::new(file, Location::Line(line), m);
    let mut pos = 0;
    let mut line = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line += 1;
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .ok_or_else(|| err(line, "the header ends without 'end_header'".into()))?;
        let text = String::from_utf8_lossy(&bytes[pos..pos + end]);
        let text = text.trim();
        pos += end + 1;
        let mut tok = text.split_whitespace();
        let word = tok.next().unwrap_or("");
        if line == 1 {
            if word != "ply" {
                return Err(err(1, format!("expected 'ply' on the first line, found '{text}'")));
            }
            continue;
        }
        match word {
            "format" => {
                encoding = Some(match tok.next() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::Binary { little: true },
                    Some("binary_big_endian") => Encoding::Binary { little: false },
                    other => {
                        return Err(err(
                            line,
                            format!(
                                "format '{}' is not ascii, binary_little_endian or \
                                 binary_big_endian",
                                other.unwrap_or("")
                            ),
                        ));
                    }
                });
            }
            "element" => {
                let name = tok.next().unwrap_or("").to_string();
                let count = tok
                    .next()
                    .and_then(|c| c.parse().ok())
                    .ok_or_else(|| err(line, format!("element '{name}' needs a count")))?;
                elements.push(Element { name, count, properties: Vec::new(), line });
            }
            "property" => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| err(line, "a property before any element".into()))?;
                let words: Vec<&str> = tok.collect();
                let bad = || err(line, format!("unknown property type in '{text}'"));
                let (property, name) = match words.as_slice() {
                    ["list", c, i, name] => (
                        Property::List(
                            Scalar::parse(c).ok_or_else(bad)?,
                            Scalar::parse(i).ok_or_else(bad)?,
                        ),
                        name,
                    ),
                    [t, name] => (Property::Scalar(Scalar::parse(t).ok_or_else(bad)?), name),
                    _ => return Err(err(line, format!("malformed property line '{text}'"))),
                };
                e.properties.push((name.to_string(), property));
            }
            "end_header" => break,
            "comment" | "obj_info" | "" => {}
            other => return Err(err(line, format!("unknown header keyword '{other}'"))),
        }
    }
    let encoding = encoding.ok_or_else(|| err(line, "the header has no 'format' line".into()))?;
    Ok((encoding, elements, pos))
}

/// The `vertex` element's index and the indices of its `x`, `y`, `z` properties.
fn vertex_layout(elements: &[Element], file: &Path) -> Result<(usize, [usize; 3]), ParseError> {
    let v = elements.iter().position(|e| e.name == "vertex").ok_or_else(|| {
        ParseError::new(file, Location::File, "no 'element vertex' in the header: no points")
    })?;
    let e = &elements[v];
    let mut xyz = [usize::MAX; 3];
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        xyz[k] = e
            .properties
            .iter()
            .position(|(n, p)| n == axis && matches!(p, Property::Scalar(_)))
            .ok_or_else(|| {
                ParseError::new(
                    file,
                    Location::Line(e.line),
                    format!("the vertex element has no scalar property '{axis}'"),
                )
            })?;
    }
    Ok((v, xyz))
}

/// Reads the vertices of a PLY file.
pub fn read(bytes: &[u8], file: &Path) -> Result<Vec<Point3<f64>>, ParseError> {
    let bytes = super::strip_bom(bytes);
    let (encoding, elements, start) = header(bytes, file)?;
    let (v, xyz) = vertex_layout(&elements, file)?;
    match encoding {
        Encoding::Ascii => {
            read_ascii(&bytes[start..], file, &elements, v, xyz, line_of(bytes, start))
        }
        Encoding::Binary { little } => {
            read_binary(&bytes[start..], file, &elements, v, xyz, little, start)
        }
    }
}

fn line_of(bytes: &[u8], pos: usize) -> usize {
    bytes[..pos].iter().filter(|&&b| b == b'\n').count() + 1
}

fn read_ascii(
    data: &[u8],
    file: &Path,
    elements: &[Element],
    v: usize,
    xyz: [usize; 3],
    first_line: usize,
) -> Result<Vec<Point3<f64>>, ParseError> {
    let text = String::from_utf8_lossy(data);
    let mut lines = text.lines().enumerate().map(|(i, l)| (first_line + i, l));
    let eof =
        |what: &str| ParseError::new(file, Location::File, format!("the file ends before {what}"));
    let mut points = Vec::with_capacity(elements[v].count.min(data.len() / 6));
    for (ei, e) in elements.iter().enumerate().take(v + 1) {
        for row in 0..e.count {
            let (ln, l) =
                lines.next().ok_or_else(|| eof(&format!("{} {row} of {}", e.name, e.count)))?;
            if ei < v {
                continue; // an element before the vertices: one per line
            }
            let words: Vec<&str> = l.split_whitespace().collect();
            let mut p = [0.0; 3];
            for (k, &i) in xyz.iter().enumerate() {
                // Scalar properties before index i: lists before it make the position vary.
                let at = ascii_position(&e.properties, &words, i).ok_or_else(|| {
                    ParseError::new(
                        file,
                        Location::Line(ln),
                        format!("vertex {row}: too few values"),
                    )
                })?;
                p[k] = super::parse_field(file, ln, words[at], "a vertex coordinate")?;
            }
            points.push(Point3::new(p[0], p[1], p[2]));
        }
    }
    Ok(points)
}

/// The word index of property `i` in an ASCII row.
fn ascii_position(props: &[(String, Property)], words: &[&str], i: usize) -> Option<usize> {
    let mut at = 0;
    for (_, p) in &props[..i] {
        match p {
            Property::Scalar(_) => at += 1,
            Property::List(..) => {
                let n: usize = words.get(at)?.parse().ok()?;
                at += 1 + n;
            }
        }
    }
    (at < words.len()).then_some(at)
}

fn read_binary(
    data: &[u8],
    file: &Path,
    elements: &[Element],
    v: usize,
    xyz: [usize; 3],
    little: bool,
    offset: usize,
) -> Result<Vec<Point3<f64>>, ParseError> {
    let short = |at: usize, what: String| {
        ParseError::new(file, Location::Byte(offset + at), format!("the file ends inside {what}"))
    };
    let mut pos = 0;
    let mut points = Vec::new();
    for (ei, e) in elements.iter().enumerate().take(v + 1) {
        let min_row: usize = e
            .properties
            .iter()
            .map(|(_, p)| match p {
                Property::Scalar(s) => s.size(),
                Property::List(c, _) => c.size(),
            })
            .sum();
        if e.count.saturating_mul(min_row) > data.len() - pos {
            return Err(short(pos, format!("the {} {} declared by the header", e.count, e.name)));
        }
        if ei == v {
            points.reserve(e.count);
        }
        for row in 0..e.count {
            let mut p = [0.0; 3];
            for (i, (_, prop)) in e.properties.iter().enumerate() {
                let what = || format!("{} {row}", e.name);
                match *prop {
                    Property::Scalar(s) => {
                        let b = data.get(pos..pos + s.size()).ok_or_else(|| short(pos, what()))?;
                        if let Some(k) = xyz.iter().position(|&x| x == i).filter(|_| ei == v) {
                            p[k] = s.decode(b, little);
                        }
                        pos += s.size();
                    }
                    Property::List(c, item) => {
                        let b = data.get(pos..pos + c.size()).ok_or_else(|| short(pos, what()))?;
                        let n = c.decode(b, little);
                        if !(n >= 0.0 && n.fract() == 0.0) {
                            return Err(short(pos, format!("{} (a negative list length)", what())));
                        }
                        pos += c.size();
                        let len = (n as usize).saturating_mul(item.size());
                        if len > data.len() - pos {
                            return Err(short(pos, what()));
                        }
                        pos += len;
                    }
                }
            }
            if ei == v {
                points.push(Point3::new(p[0], p[1], p[2]));
            }
        }
    }
    Ok(points)
}

/// Writes `points` as an ASCII PLY file (vertices only, round-trip-exact coordinates).
pub fn write(w: &mut dyn Write, points: &[Point3<f64>]) -> io::Result<()> {
    writeln!(w, "ply\nformat ascii 1.0\ncomment brainshift")?;
    writeln!(w, "element vertex {}", points.len())?;
    writeln!(w, "property double x\nproperty double y\nproperty double z\nend_header")?;
    for p in points {
        writeln!(w, "{} {} {}", p.x, p.y, p.z)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binary(little: bool) -> Vec<u8> {
        let order = if little { "binary_little_endian" } else { "binary_big_endian" };
        let mut b = format!(
            "ply\nformat {order} 1.0\ncomment two triangles\nelement face 1\n\
             property list uchar int vertex_indices\nelement vertex 2\nproperty float x\n\
             property uchar red\nproperty double y\nproperty short z\nend_header\n"
        )
        .into_bytes();
        // The face: 3 indices (a list before the vertices, to be skipped).
        b.push(3);
        for i in [0i32, 1, 0] {
            b.extend(if little { i.to_le_bytes() } else { i.to_be_bytes() });
        }
        for (x, y, z) in [(1.5f32, -2.25f64, 7i16), (0.0, 1e3, -1)] {
            b.extend(if little { x.to_le_bytes() } else { x.to_be_bytes() });
            b.push(200);
            b.extend(if little { y.to_le_bytes() } else { y.to_be_bytes() });
            b.extend(if little { z.to_le_bytes() } else { z.to_be_bytes() });
        }
        b
    }

    #[test]
    fn binary_files_of_either_byte_order_with_lists_and_extra_properties() {
        for little in [true, false] {
            let p = read(&binary(little), Path::new("a.ply")).unwrap();
            assert_eq!(p, vec![Point3::new(1.5, -2.25, 7.0), Point3::new(0.0, 1e3, -1.0)]);
        }
        // Truncated: an error naming the byte offset, never a panic.
        let b = binary(true);
        for cut in [b.len() - 1, b.len() - 9, 120] {
            let e = read(&b[..cut], Path::new("a.ply")).unwrap_err();
            assert!(e.to_string().contains("a.ply"), "{e}");
        }
    }

    #[test]
    fn ascii_round_trip_and_errors_name_the_line() {
        let pts = vec![Point3::new(0.1, -2.0, 3.3e-5), Point3::new(1.0 / 3.0, 2.0, 3.0)];
        let mut b = Vec::new();
        write(&mut b, &pts).unwrap();
        assert_eq!(read(&b, Path::new("w.ply")).unwrap(), pts);
        let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                    property float z\nproperty list uchar int n\nend_header\n1 2 3 0\n4 five 6 0\n";
        let e = read(text.as_bytes(), Path::new("s.ply")).unwrap_err();
        assert_eq!(e.location, Location::Line(10), "{e}");
        let no_z = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n";
        assert!(read(no_z.as_bytes(), Path::new("n.ply")).unwrap_err().to_string().contains("'z'"));
        let huge = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
        assert!(read(huge.as_bytes(), Path::new("h.ply")).is_err());
    }
}
