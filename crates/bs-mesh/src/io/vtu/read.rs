//! The VTU reader (and the points of VTK XML polydata).

use std::collections::HashMap;
use std::path::Path;

use base64::Engine;
use nalgebra::Point3;
use quick_xml::events::{BytesStart, Event};

use super::cells::{Array, Cells, Data, assemble, points_of};
use crate::Mesh;
use crate::io::{Fields, Location, ParseError};

/// A DataArray element as found in the XML, before decoding.
#[derive(Debug)]
struct RawArray {
    section: String,
    attrs: HashMap<String, String>,
    text: Vec<u8>,
    pos: usize,
}

fn attributes(
    e: &BytesStart<'_>,
    file: &Path,
    pos: usize,
) -> Result<HashMap<String, String>, ParseError> {
    let mut map = HashMap::new();
    for a in e.attributes() {
        let a = a.map_err(|x| {
            ParseError::new(file, Location::Byte(pos), format!("malformed XML attribute: {x}"))
        })?;
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a.unescape_value().map_err(|x| {
            ParseError::new(file, Location::Byte(pos), format!("malformed XML attribute: {x}"))
        })?;
        map.insert(key, value.into_owned());
    }
    Ok(map)
}

fn lenient_b64() -> base64::engine::GeneralPurpose {
    use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
    GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        GeneralPurposeConfig::new()
            .with_decode_padding_mode(DecodePaddingMode::Indifferent)
            .with_decode_allow_trailing_bits(true),
    )
}

/// Decodes base64 text that may be several separately encoded pieces (VTK encodes a
/// compressed block's header apart from its data): the stream is cut after each run of `=`.
fn b64_decode(text: &[u8]) -> Result<Vec<u8>, String> {
    let clean: Vec<u8> = text.iter().copied().filter(|b| !b.is_ascii_whitespace()).collect();
    let engine = lenient_b64();
    let mut out = Vec::with_capacity(clean.len() / 4 * 3 + 3);
    let mut start = 0;
    let mut i = 0;
    while i < clean.len() {
        if clean[i] == b'=' {
            let mut j = i;
            while j < clean.len() && clean[j] == b'=' {
                j += 1;
            }
            engine
                .decode_vec(&clean[start..j], &mut out)
                .map_err(|e| format!("bad base64: {e}"))?;
            start = j;
            i = j;
        } else {
            i += 1;
        }
    }
    if start < clean.len() {
        engine.decode_vec(&clean[start..], &mut out).map_err(|e| format!("bad base64: {e}"))?;
    }
    Ok(out)
}

#[derive(Debug, Clone, Copy)]
struct Layout {
    header64: bool,
    zlib: bool,
}

impl Layout {
    fn hsize(self) -> usize {
        if self.header64 { 8 } else { 4 }
    }

    fn header(self, raw: &[u8], k: usize) -> Result<u64, String> {
        let h = self.hsize();
        let b = raw.get(k * h..(k + 1) * h).ok_or_else(|| {
            format!("binary block ends inside its header ({} bytes available)", raw.len())
        })?;
        Ok(if self.header64 {
            u64::from_le_bytes(b.try_into().expect("8 bytes"))
        } else {
            u32::from_le_bytes(b.try_into().expect("4 bytes")) as u64
        })
    }

    /// Decodes one binary block (header + data, possibly compressed) from the start of `raw`.
    fn block(self, raw: &[u8]) -> Result<Vec<u8>, String> {
        let h = self.hsize();
        if !self.zlib {
            let n = self.header(raw, 0)?;
            let avail = raw.len() - h;
            if n > avail as u64 {
                return Err(format!("binary block declares {n} bytes but only {avail} follow"));
            }
            return Ok(raw[h..h + n as usize].to_vec());
        }
        let nblocks = self.header(raw, 0)?;
        let block_size = self.header(raw, 1)?;
        let last_size = self.header(raw, 2)?;
        if nblocks > (raw.len() / h) as u64 {
            return Err(format!(
                "compressed header declares {nblocks} blocks, more than the data holds"
            ));
        }
        let nblocks = nblocks as usize;
        let mut pos = (3 + nblocks) * h;
        if pos > raw.len() {
            return Err("compressed block header is truncated".into());
        }
        let mut out = Vec::new();
        for b in 0..nblocks {
            let csize = self.header(raw, 3 + b)?;
            let end =
                (pos as u64).checked_add(csize).filter(|&e| e <= raw.len() as u64).ok_or_else(
                    || format!("compressed block {b} declares {csize} bytes beyond the data"),
                )? as usize;
            let expect = if b + 1 == nblocks && last_size != 0 { last_size } else { block_size };
            let before = out.len();
            inflate_zlib(&raw[pos..end], expect, &mut out)
                .map_err(|e| format!("zlib block {b}: {e}"))?;
            if (out.len() - before) as u64 != expect {
                return Err(format!(
                    "zlib block {b} inflates to {} bytes, header says {expect}",
                    out.len() - before
                ));
            }
            pos = end;
        }
        Ok(out)
    }
}

fn type_size(ty: &str) -> Option<usize> {
    Some(match ty {
        "Int8" | "UInt8" => 1,
        "Int16" | "UInt16" => 2,
        "Int32" | "UInt32" | "Float32" => 4,
        "Int64" | "UInt64" | "Float64" => 8,
        _ => return None,
    })
}

fn convert_le(ty: &str, b: &[u8]) -> Result<Data, String> {
    let size = type_size(ty).ok_or_else(|| format!("unsupported data type '{ty}'"))?;
    if !b.len().is_multiple_of(size) {
        return Err(format!("{} bytes is not a whole number of {ty} values", b.len()));
    }
    let ch = b.chunks_exact(size);
    let arr = |c: &[u8]| -> [u8; 8] {
        let mut a = [0u8; 8];
        a[..c.len()].copy_from_slice(c);
        a
    };
    Ok(match ty {
        "Float64" => Data::F(ch.map(|c| f64::from_le_bytes(arr(c))).collect()),
        "Float32" => Data::F(
            ch.map(|c| f32::from_le_bytes(arr(c)[..4].try_into().expect("4")) as f64).collect(),
        ),
        "Int8" => Data::I(ch.map(|c| c[0] as i8 as i64).collect()),
        "UInt8" => Data::I(ch.map(|c| c[0] as i64).collect()),
        "Int16" => Data::I(ch.map(|c| i16::from_le_bytes([c[0], c[1]]) as i64).collect()),
        "UInt16" => Data::I(ch.map(|c| u16::from_le_bytes([c[0], c[1]]) as i64).collect()),
        "Int32" => Data::I(
            ch.map(|c| i32::from_le_bytes(arr(c)[..4].try_into().expect("4")) as i64).collect(),
        ),
        "UInt32" => Data::I(
            ch.map(|c| u32::from_le_bytes(arr(c)[..4].try_into().expect("4")) as i64).collect(),
        ),
        _ => Data::I(ch.map(|c| i64::from_le_bytes(arr(c))).collect()), // Int64, UInt64 (bits)
    })
}

/// Parses whitespace-separated ASCII values of type `ty`.
pub(crate) fn parse_ascii(ty_is_float: bool, text: &str) -> Result<Data, String> {
    let tok = text.split_whitespace();
    if ty_is_float {
        tok.map(|t| t.parse::<f64>().map_err(|_| format!("expected a number, found '{t}'")))
            .collect::<Result<_, _>>()
            .map(Data::F)
    } else {
        tok.map(|t| {
            t.parse::<i64>()
                .or_else(|_| t.parse::<u64>().map(|u| u as i64))
                .map_err(|_| format!("expected an integer, found '{t}'"))
        })
        .collect::<Result<_, _>>()
        .map(Data::I)
    }
}

/// Parses a VTU unstructured grid.
pub fn read(bytes: &[u8], file: &Path) -> Result<(Mesh, Fields), ParseError> {
    const SECTIONS: &[&str] = &["Points", "Cells", "PointData", "CellData"];
    let xml = read_xml(bytes, file, "UnstructuredGrid", SECTIONS)?;
    let err = |pos: usize, msg: String| ParseError::new(file, Location::Byte(pos), msg);
    let (npoints, ncells) = (xml.count("NumberOfPoints", file)?, xml.count("NumberOfCells", file)?);
    let mut points = None;
    let mut cells = Cells { loc: Some(Location::Byte(xml.pos)), ..Default::default() };
    let (mut pdata, mut cdata) = (Vec::new(), Vec::new());
    for (section, a) in xml.arrays {
        match section.as_str() {
            "Points" => points = Some(a),
            "Cells" => {
                let ints = match a.data {
                    Data::I(v) => v,
                    Data::F(_) => {
                        let pos = match a.loc {
                            Location::Byte(p) => p,
                            _ => xml.pos,
                        };
                        return Err(err(
                            pos,
                            format!(
                                "DataArray '{}': cell arrays must have an integer type",
                                a.name
                            ),
                        ));
                    }
                };
                match a.name.as_str() {
                    "connectivity" => cells.connectivity = ints,
                    "offsets" => cells.offsets = ints,
                    "types" => cells.types = ints,
                    _ => {}
                }
            }
            "PointData" => pdata.push(a),
            "CellData" => cdata.push(a),
            _ => {}
        }
    }
    let points = points.ok_or_else(|| err(xml.pos, "<Points> has no DataArray".into()))?;
    if cells.types.len() != ncells {
        return Err(err(
            xml.pos,
            format!(
                "NumberOfCells is {ncells} but the 'types' array has {} entries",
                cells.types.len()
            ),
        ));
    }
    let (mesh, mut fields) = assemble(file, npoints, &points, &cells, pdata, cdata)?;
    fields.field_data = xml.field_data;
    Ok((mesh, fields))
}

/// The points of a VTK XML PolyData file (`.vtp`): its vertices, whatever cells it has.
pub fn read_polydata_points(bytes: &[u8], file: &Path) -> Result<Vec<Point3<f64>>, ParseError> {
    let xml = read_xml(bytes, file, "PolyData", &["Points"])?;
    let n = xml.count("NumberOfPoints", file)?;
    let (_, points) = xml.arrays.into_iter().find(|(s, _)| s == "Points").ok_or_else(|| {
        ParseError::new(file, Location::Byte(xml.pos), "<Points> has no DataArray")
    })?;
    points_of(file, n, &points)
}

/// A VTK XML file of one piece with the arrays of some sections decoded: what the `.vtu`
/// and `.vtp` readers share.
pub(crate) struct XmlPiece {
    /// The `<Piece>` element's attributes and byte offset.
    attrs: HashMap<String, String>,
    pos: usize,
    /// The decoded arrays with the section each is in, in file order.
    arrays: Vec<(String, Array)>,
    /// The dataset's String field data (name, value), e.g. `SPACE`.
    field_data: Vec<(String, String)>,
}

impl XmlPiece {
    /// A count attribute of the piece.
    fn count(&self, key: &str, file: &Path) -> Result<usize, ParseError> {
        let err = |m: String| ParseError::new(file, Location::Byte(self.pos), m);
        self.attrs
            .get(key)
            .ok_or_else(|| err(format!("<Piece> lacks the {key} attribute")))?
            .trim()
            .parse()
            .map_err(|_| err(format!("<Piece> attribute {key} is not a count")))
    }
}

/// Reads the markup of a VTK XML file of type `kind` and decodes the data arrays of
/// `sections` (and the dataset's String field data).
fn read_xml(
    bytes: &[u8],
    file: &Path,
    kind: &str,
    sections: &[&str],
) -> Result<XmlPiece, ParseError> {
    let (xml_src, appended) = split_appended(bytes, file)?;
    let markup = scan_markup(&xml_src, file, kind)?;
    let appended = appended.map(|data| (markup.appended_encoding.clone(), data));
    let (piece_attrs, piece_pos) = markup.piece;

    // Appended base64: an array's encoded block ends where the next one starts.
    let mut offsets: Vec<usize> = markup
        .arrays
        .iter()
        .filter_map(|a| a.attrs.get("offset").and_then(|o| o.trim().parse().ok()))
        .collect();
    offsets.sort_unstable();
    offsets.dedup();

    let mut decoded = Vec::new();
    let mut field_data = Vec::new();
    for a in markup.arrays {
        // Arrays outside the asked sections and the dataset's field data carry nothing the
        // caller needs.
        if a.section == "FieldData" {
            field_data.extend(field_string(&a));
        } else if sections.contains(&a.section.as_str()) {
            let array = decode_array(&a, file, markup.layout, appended.as_ref(), &offsets)?;
            decoded.push((a.section, array));
        }
    }
    Ok(XmlPiece { attrs: piece_attrs, pos: piece_pos, arrays: decoded, field_data })
}

/// The markup to parse (borrowed, or copied and closed before the appended section) and
/// the appended section's data, if any.
type Split<'a> = (std::borrow::Cow<'a, [u8]>, Option<&'a [u8]>);

/// The markup to parse and the appended data. The appended section is not XML (raw binary
/// may hold anything): only the markup before it is parsed (closed again), and its data
/// starts after the `_`.
fn split_appended<'a>(bytes: &'a [u8], file: &Path) -> Result<Split<'a>, ParseError> {
    let err = |pos: usize, msg: &str| ParseError::new(file, Location::Byte(pos), msg);
    let Some(p) = find(bytes, b"<AppendedData") else {
        return Ok((std::borrow::Cow::Borrowed(bytes), None));
    };
    let q = p + bytes[p..]
        .iter()
        .position(|&b| b == b'>')
        .ok_or_else(|| err(p, "unterminated <AppendedData> tag"))?;
    let mut u = q + 1;
    while u < bytes.len() && bytes[u].is_ascii_whitespace() {
        u += 1;
    }
    if bytes.get(u) != Some(&b'_') {
        return Err(err(u, "appended data must start with '_'"));
    }
    let data_end = rfind(bytes, b"</AppendedData>").filter(|&e| e > u).unwrap_or(bytes.len());
    let mut xml = bytes[..=q].to_vec();
    xml.extend_from_slice(b"</AppendedData></VTKFile>");
    Ok((std::borrow::Cow::Owned(xml), Some(&bytes[u + 1..data_end])))
}

/// What the markup says: the data layout, the one piece (attributes, position), the data
/// arrays in file order with their text, and the appended data's encoding.
struct Markup {
    layout: Layout,
    piece: (HashMap<String, String>, usize),
    arrays: Vec<RawArray>,
    appended_encoding: String,
}

/// Reads the markup of a VTK XML file of type `kind`: one `<VTKFile>`, one `<Piece>`.
fn scan_markup(xml_src: &[u8], file: &Path, kind: &str) -> Result<Markup, ParseError> {
    let err = |pos: usize, msg: String| ParseError::new(file, Location::Byte(pos), msg);
    let mut reader = quick_xml::Reader::from_reader(xml_src);
    let mut stack: Vec<String> = Vec::new();
    let mut layout = None;
    let mut piece: Option<(HashMap<String, String>, usize)> = None;
    let mut arrays: Vec<RawArray> = Vec::new();
    let mut appended_encoding = "raw".to_string();
    let mut open_array = false;
    loop {
        let pos = reader.buffer_position() as usize;
        let ev = reader
            .read_event()
            .map_err(|e| err(reader.error_position() as usize, format!("malformed XML: {e}")))?;
        let (start, empty) = match &ev {
            Event::Start(s) => (Some(s.clone()), false),
            Event::Empty(s) => (Some(s.clone()), true),
            Event::Text(t) if open_array => {
                if let Some(a) = arrays.last_mut() {
                    a.text.extend_from_slice(t.as_ref());
                }
                (None, false)
            }
            Event::CData(t) if open_array => {
                if let Some(a) = arrays.last_mut() {
                    a.text.extend_from_slice(t.as_ref());
                }
                (None, false)
            }
            Event::End(_) => {
                stack.pop();
                open_array = false;
                (None, false)
            }
            Event::Eof => break,
            _ => (None, false),
        };
        let Some(s) = start else { continue };
        let name = String::from_utf8_lossy(s.name().as_ref()).into_owned();
        let at = attributes(&s, file, pos)?;
        match name.as_str() {
            "VTKFile" => layout = Some(vtkfile_layout(&at, kind, file, pos)?),
            "Piece" => {
                if piece.is_some() {
                    return Err(err(pos, "VTK XML file with several pieces; merge them into one (ParaView: Merge Blocks) before use".into()));
                }
                piece = Some((at.clone(), pos));
            }
            "AppendedData" => {
                appended_encoding = at.get("encoding").cloned().unwrap_or_else(|| "raw".into());
            }
            "DataArray" => {
                let section = stack.last().cloned().unwrap_or_default();
                arrays.push(RawArray { section, attrs: at, text: Vec::new(), pos });
                open_array = !empty;
            }
            _ => {}
        }
        if !empty {
            stack.push(name);
        }
    }
    let layout = layout.ok_or_else(|| {
        ParseError::new(file, Location::File, "no <VTKFile> element: not a VTK XML file")
    })?;
    let piece = piece.ok_or_else(|| {
        ParseError::new(
            file,
            Location::File,
            format!("no <Piece> element: the dataset is empty or not of type {kind}"),
        )
    })?;
    Ok(Markup { layout, piece, arrays, appended_encoding })
}

/// The `<VTKFile>` element's checks (type, byte order) and the data layout it declares
/// (header size, compression).
fn vtkfile_layout(
    at: &HashMap<String, String>,
    kind: &str,
    file: &Path,
    pos: usize,
) -> Result<Layout, ParseError> {
    let err = |msg: String| ParseError::new(file, Location::Byte(pos), msg);
    if let Some(t) = at.get("type").filter(|t| *t != kind) {
        let holds = match kind {
            "UnstructuredGrid" => "only UnstructuredGrid (.vtu) holds a volume mesh",
            _ => "only PolyData (.vtp) holds a point cloud or a surface here",
        };
        return Err(err(format!("VTK file of type '{t}'; {holds}")));
    }
    if at.get("byte_order").is_some_and(|b| b == "BigEndian") {
        return Err(err("big-endian VTU is not supported; save it little-endian".into()));
    }
    let header64 = match at.get("header_type").map(String::as_str) {
        None | Some("UInt32") => false,
        Some("UInt64") => true,
        Some(o) => return Err(err(format!("header_type '{o}' is not UInt32 or UInt64"))),
    };
    let zlib = match at.get("compressor").map(String::as_str) {
        None | Some("") => false,
        Some("vtkZLibDataCompressor") => true,
        Some(o) => {
            return Err(err(format!(
                "data compressed with {o} is not supported; save uncompressed or \
                 with zlib (ParaView: Data Mode Binary, Compressor ZLib or None)"
            )));
        }
    };
    Ok(Layout { header64, zlib })
}

/// A dataset-level String in ASCII (e.g. SPACE) as (name, value); other field data is not
/// used.
fn field_string(a: &RawArray) -> Option<(String, String)> {
    let ascii = a.attrs.get("format").is_none_or(|f| f == "ascii");
    if a.attrs.get("type").is_none_or(|t| t != "String") || !ascii {
        return None;
    }
    let text = String::from_utf8_lossy(&a.text);
    let bytes: Vec<u8> = text
        .split_ascii_whitespace()
        .map_while(|b| b.parse::<u8>().ok())
        .take_while(|&b| b != 0)
        .collect();
    let name = a.attrs.get("Name").cloned().unwrap_or_default();
    Some((name, String::from_utf8_lossy(&bytes).into_owned()))
}

/// One data array decoded from ASCII, inline base64 or the appended section (raw or base64,
/// an encoded block ending at the next array's offset).
fn decode_array(
    a: &RawArray,
    file: &Path,
    layout: Layout,
    appended: Option<&(String, &[u8])>,
    offsets: &[usize],
) -> Result<Array, ParseError> {
    let fail = |m: String| {
        ParseError::new(
            file,
            Location::Byte(a.pos),
            format!("DataArray '{}': {m}", a.attrs.get("Name").map_or("", |s| s)),
        )
    };
    let ty = a.attrs.get("type").cloned().unwrap_or_default();
    type_size(&ty).ok_or_else(|| {
        fail(format!("type '{ty}' is not supported (use Float32/64, (U)Int8/16/32/64)"))
    })?;
    let format = a.attrs.get("format").map(String::as_str).unwrap_or("ascii");
    let data = match format {
        "ascii" => {
            let text =
                std::str::from_utf8(&a.text).map_err(|_| fail("ASCII data is not text".into()))?;
            parse_ascii(ty.starts_with("Float"), text).map_err(fail)?
        }
        "binary" => {
            let raw = b64_decode(&a.text).map_err(fail)?;
            convert_le(&ty, &layout.block(&raw).map_err(fail)?).map_err(fail)?
        }
        "appended" => {
            let (encoding, data) = appended.ok_or_else(|| {
                fail("format=\"appended\" but the file has no <AppendedData>".into())
            })?;
            let off: usize = a
                .attrs
                .get("offset")
                .and_then(|o| o.trim().parse().ok())
                .ok_or_else(|| fail("appended array without a valid offset".into()))?;
            if off > data.len() {
                return Err(fail(format!(
                    "offset {off} is beyond the {} bytes of appended data",
                    data.len()
                )));
            }
            let raw = if encoding == "base64" {
                let next = offsets
                    .iter()
                    .copied()
                    .find(|&o| o > off)
                    .unwrap_or(data.len())
                    .min(data.len());
                b64_decode(&data[off..next]).map_err(fail)?
            } else if encoding == "raw" {
                data[off..].to_vec()
            } else {
                return Err(fail(format!("appended encoding '{encoding}' is not raw or base64")));
            };
            convert_le(&ty, &layout.block(&raw).map_err(fail)?).map_err(fail)?
        }
        o => return Err(fail(format!("format '{o}' is not ascii, binary or appended"))),
    };
    let ncomp: usize = match a.attrs.get("NumberOfComponents") {
        None => 1,
        Some(c) => c
            .trim()
            .parse()
            .map_err(|_| fail(format!("NumberOfComponents '{c}' is not a count")))?,
    };
    let name = a.attrs.get("Name").cloned().unwrap_or_default();
    Ok(Array { name, ncomp, data, loc: Location::Byte(a.pos) })
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn rfind(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).rposition(|w| w == needle)
}

/// Inflates one zlib stream (checksum verified by miniz_oxide), appending at most `limit`
/// bytes to `out`: a corrupted header cannot make us allocate more than it declared.
fn inflate_zlib(data: &[u8], limit: u64, out: &mut Vec<u8>) -> Result<(), String> {
    let limit = usize::try_from(limit).map_err(|_| "block size exceeds memory".to_string())?;
    let bytes = miniz_oxide::inflate::decompress_to_vec_zlib_with_limit(data, limit).map_err(
        |e| match e.status {
            miniz_oxide::inflate::TINFLStatus::HasMoreOutput => {
                "inflates to more bytes than the header declares".to_string()
            }
            miniz_oxide::inflate::TINFLStatus::Adler32Mismatch => {
                "zlib checksum mismatch (corrupted data)".to_string()
            }
            other => format!("corrupted zlib data ({other:?})"),
        },
    )?;
    out.extend_from_slice(&bytes);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::{Encoding, write};
    use super::*;

    fn unhex(s: &str) -> Vec<u8> {
        (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap()).collect()
    }

    #[test]
    fn inflate_matches_python_zlib() {
        // Vectors from Python's zlib.compress: level 0 (stored block) and level 9 (fixed
        // Huffman with back-references). The sphere fixture exercises dynamic Huffman.
        let mut out = Vec::new();
        inflate_zlib(&unhex("7801010300fcff616263024d0127"), 3, &mut out).unwrap();
        assert_eq!(out, b"abc");
        let hello = unhex("78dacb48cdc9c957c8402701680308b1");
        out.clear();
        inflate_zlib(&hello, 23, &mut out).unwrap();
        assert_eq!(out, b"hello hello hello hello");
        // A header announcing fewer bytes than the stream holds is an error, not a big buffer.
        out.clear();
        assert!(inflate_zlib(&hello, 10, &mut out).unwrap_err().contains("more bytes"));
        let mut bad = hello.clone();
        *bad.last_mut().unwrap() ^= 1;
        out.clear();
        assert_eq!(
            inflate_zlib(&bad, 23, &mut out).unwrap_err(),
            "zlib checksum mismatch (corrupted data)"
        );
    }

    #[test]
    fn base64_pieces_with_inner_padding_decode() {
        // VTK encodes a compressed block's header apart from the data: "AQ==" + "AgM=".
        assert_eq!(b64_decode(b"AQ==\nAgM=").unwrap(), vec![1, 2, 3]);
    }

    /// The SPACE string is written as VTK writes String field data (character codes and a
    /// terminating 0) before the piece, and the file reads back to the same mesh and frame.
    #[test]
    fn space_field_data_is_written_and_read_back() {
        let mesh = crate::structured::box_mesh(1, 1.0, true);
        let mut out = Vec::new();
        let fields =
            Fields { field_data: vec![("SPACE".into(), "RAS".into())], ..Fields::default() };
        write(&mut out, &mesh, &fields, Encoding::Inline).unwrap();
        let text = String::from_utf8(out.clone()).unwrap();
        let fd = text.find("<FieldData>").unwrap();
        assert!(fd < text.find("<Piece").unwrap());
        assert!(text.contains(
            "type=\"String\" Name=\"SPACE\" NumberOfTuples=\"1\" format=\"ascii\">\n82 65 83 0\n"
        ));
        let (back, back_fields) = read(&out, Path::new("t.vtu")).unwrap();
        assert_eq!(back.nodes, mesh.nodes);
        assert_eq!(back.elements, mesh.elements);
        assert_eq!(back_fields.field_data, fields.field_data);
    }
}
