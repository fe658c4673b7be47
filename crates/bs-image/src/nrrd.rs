//! NRRD images (`.nrrd`, and `.nhdr` headers with detached data), 3D Slicer's default
//! volume format, read and written.
//!
//! Read: NRRD0001 to NRRD0005 headers; 3-D scalar images (a 4-D file whose first axis has
//! size 1 too); every scalar type; `raw` and `gzip` encodings; little or big endian; `space`
//! `left-posterior-superior` (LPS, Slicer's and ITK's files) or `right-anterior-superior`
//! (RAS), with `space directions` and `space origin` (world map in mm; LPS is converted to
//! brainshift's RAS world); `space units` mm (or m, µm: scaled); `byte skip`, `line skip`,
//! `data file` (one detached file, relative to the header). Slicer's segmentations
//! (`.seg.nrrd`, one layer) are labelmaps like any other. Refused, each naming the file and
//! the header field with the fix: no `space` (no anatomical frame, never guessed), a `space`
//! that contradicts `space dimension` or the number of `space directions`, encodings other
//! than raw and gzip, a second component (vectors, multi-layer segmentations), data shorter
//! than the header says.
//!
//! Written: float32 images, int32 labelmaps and displacement fields, gzip-compressed, in
//! LPS (what Slicer and ITK write). A field is a 4-D vector NRRD — `kinds: vector domain
//! domain domain`, `space directions: none (…) (…) (…)`, LPS vectors — which ITK reads as a
//! vector image (SimpleITK: a displacement field) and 3D Slicer loads as a transform.

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::Path;

use nalgebra::Matrix4;

use crate::{Grid, ImageError, Space, Volume};

/// Voxel data larger than this are refused before anything is allocated.
pub const MAX_DATA_BYTES: u64 = crate::nifti::MAX_DATA_BYTES;

fn invalid(file: &Path, message: impl Into<String>) -> ImageError {
    ImageError::Invalid { file: file.to_path_buf(), message: message.into() }
}

fn io(file: &Path, message: impl Into<String>) -> ImageError {
    ImageError::Io { file: file.to_path_buf(), message: message.into() }
}

/// A scalar type of NRRD's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "signed char" | "int8" | "int8_t" => Scalar::I8,
            "uchar" | "unsigned char" | "uint8" | "uint8_t" => Scalar::U8,
            "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
                Scalar::I16
            }
            "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
                Scalar::U16
            }
            "int" | "signed int" | "int32" | "int32_t" => Scalar::I32,
            "uint" | "unsigned int" | "uint32" | "uint32_t" => Scalar::U32,
            "longlong"
            | "long long"
            | "long long int"
            | "signed long long"
            | "signed long long int"
            | "int64"
            | "int64_t" => Scalar::I64,
            "ulonglong"
            | "unsigned long long"
            | "unsigned long long int"
            | "uint64"
            | "uint64_t" => Scalar::U64,
            "float" => Scalar::F32,
            "double" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::I64 | Scalar::U64 | Scalar::F64 => 8,
        }
    }

    /// One value from its bytes (`big`: big-endian).
    fn value(self, b: &[u8], big: bool) -> f64 {
        let mut a = [0u8; 8];
        let n = self.size();
        a[..n].copy_from_slice(&b[..n]);
        if big {
            a[..n].reverse();
        }
        match self {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::I64 => i64::from_le_bytes(a) as f64,
            Scalar::U64 => u64::from_le_bytes(a) as f64,
            Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        }
    }
}

/// The header fields of a NRRD file (keys lower-cased), with where the data starts.
struct Header {
    fields: BTreeMap<String, String>,
    /// Byte offset of the data in the header file (attached data).
    data_offset: usize,
}

/// Splits the header off the file's bytes. `.nhdr` files are header only.
fn parse_header(file: &Path, bytes: &[u8]) -> Result<Header, ImageError> {
    let magic = bytes.get(..8).unwrap_or(bytes);
    if !(magic.starts_with(b"NRRD000") && magic.len() == 8 && (b'1'..=b'5').contains(&magic[7])) {
        return Err(invalid(
            file,
            "not a NRRD file (the first line must be NRRD0001 to NRRD0005); export the volume \
             from 3D Slicer or write it with pynrrd, ITK or teem",
        ));
    }
    let mut fields = BTreeMap::new();
    let mut pos = 0usize;
    let mut first = true;
    loop {
        let end = bytes[pos..].iter().position(|&b| b == b'\n').map(|e| pos + e);
        let line_end = end.unwrap_or(bytes.len());
        let line = String::from_utf8_lossy(&bytes[pos..line_end]);
        let line = line.trim_end_matches('\r');
        pos = end.map_or(bytes.len(), |e| e + 1);
        if first {
            first = false;
        } else if line.is_empty() {
            break; // the blank line before attached data
        } else if line.starts_with('#') {
            // a comment
        } else if let Some((k, v)) = line.split_once(": ") {
            fields.insert(k.trim().to_ascii_lowercase(), v.trim().to_string());
        } else if line.contains(":=") {
            // a key/value pair (Slicer's segment metadata): not needed
        } else {
            return Err(invalid(
                file,
                format!("header line '{line}' is neither 'field: value' nor 'key:=value'"),
            ));
        }
        if end.is_none() {
            break;
        }
    }
    Ok(Header { fields, data_offset: pos })
}

impl Header {
    fn get(&self, key: &str) -> Option<&str> {
        self.fields.get(key).map(String::as_str)
    }

    fn require(&self, file: &Path, key: &str, what: &str) -> Result<&str, ImageError> {
        self.get(key)
            .ok_or_else(|| invalid(file, format!("the header has no '{key}' field ({what})")))
    }
}

/// Parses "(x,y,z)" or "none".
fn vector(file: &Path, field: &str, s: &str) -> Result<Option<[f64; 3]>, ImageError> {
    let s = s.trim();
    if s == "none" {
        return Ok(None);
    }
    let inner = s.strip_prefix('(').and_then(|s| s.strip_suffix(')')).ok_or_else(|| {
        invalid(file, format!("'{field}': expected a vector like (1,0,0), found '{s}'"))
    })?;
    let v: Vec<f64> =
        inner
            .split(',')
            .map(|c| c.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| invalid(file, format!("'{field}': '{s}' is not a vector of numbers")))?;
    if v.len() != 3 || !v.iter().all(|x| x.is_finite()) {
        return Err(invalid(
            file,
            format!("'{field}': '{s}' has {} components; a 3-D space needs 3 finite ones", v.len()),
        ));
    }
    Ok(Some([v[0], v[1], v[2]]))
}

/// Splits a `space directions` value into its per-axis vectors (or `none`).
fn direction_list(s: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut depth = 0;
    for ch in s.chars() {
        match ch {
            '(' => {
                depth += 1;
                cur.push(ch);
            }
            ')' => {
                depth -= 1;
                cur.push(ch);
            }
            c if c.is_whitespace() && depth == 0 => {
                if !cur.is_empty() {
                    out.push(std::mem::take(&mut cur));
                }
            }
            c => cur.push(c),
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// A NRRD image's grid, values and the frame its file was written in.
struct Decoded {
    grid: Grid,
    values: Vec<f64>,
}

/// Reads and checks the header, the grid and the voxel values (as f64).
fn decode(file: &Path) -> Result<Decoded, ImageError> {
    let bytes = std::fs::read(file).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => io(file, "no such file"),
        _ => io(file, format!("could not read: {e}")),
    })?;
    let h = parse_header(file, &bytes)?;
    let dim: usize = h
        .require(file, "dimension", "the number of axes")?
        .parse()
        .map_err(|_| invalid(file, "'dimension' is not a whole number"))?;
    let sizes: Vec<usize> = h
        .require(file, "sizes", "the number of samples per axis")?
        .split_whitespace()
        .map(|s| s.parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| invalid(file, "'sizes' must be whole numbers"))?;
    if sizes.len() != dim {
        return Err(invalid(
            file,
            format!("'sizes' lists {} axes but 'dimension' is {dim}; fix one of them", sizes.len()),
        ));
    }
    // The axes: 3 spatial ones, or a leading axis of size 1.
    let (lead, spatial) = match dim {
        3 => (0, [sizes[0], sizes[1], sizes[2]]),
        4 if sizes[0] == 1 => (1, [sizes[1], sizes[2], sizes[3]]),
        4 => {
            return Err(invalid(
                file,
                format!(
                    "'sizes' {sizes:?}: {} values per voxel (a vector image or a segmentation \
                     with overlapping layers); pass one scalar volume (in Slicer: export the \
                     segmentation to a labelmap)",
                    sizes[0]
                ),
            ));
        }
        _ => {
            return Err(invalid(
                file,
                format!("'dimension' is {dim}; brainshift reads 3-D volumes (dimension 3)"),
            ));
        }
    };
    if spatial.contains(&0) {
        return Err(invalid(file, format!("'sizes' {sizes:?} has a zero")));
    }
    let scalar = {
        let t = h.require(file, "type", "the scalar type")?;
        Scalar::parse(t).ok_or_else(|| {
            invalid(file, format!("'type: {t}' is not a scalar type brainshift reads (integers of 8 to 64 bits, float, double)"))
        })?
    };
    let count = spatial.iter().product::<usize>();
    let bytes_needed = count as u64 * scalar.size() as u64;
    if bytes_needed > MAX_DATA_BYTES {
        return Err(invalid(
            file,
            format!("'sizes' {sizes:?} declares {bytes_needed} bytes, more than brainshift reads"),
        ));
    }
    let grid = grid_of(file, &h, dim, lead, spatial)?;
    let encoding = h.require(file, "encoding", "raw or gzip")?.to_ascii_lowercase();
    let gzip = match encoding.as_str() {
        "raw" => false,
        "gzip" | "gz" => true,
        other => {
            return Err(invalid(
                file,
                format!(
                    "'encoding: {other}' is not supported (raw and gzip are); re-save the \
                     volume from 3D Slicer (compressed) or with pynrrd, encoding='gzip'"
                ),
            ));
        }
    };
    let big = match h.get("endian") {
        Some("big") => true,
        Some("little") | None => false,
        Some(other) => {
            return Err(invalid(file, format!("'endian: {other}': expected little or big")));
        }
    };
    if scalar.size() > 1 && h.get("endian").is_none() {
        return Err(invalid(file, "the header has no 'endian' field (little or big)"));
    }
    let (data_file, raw_bytes) = match h.get("data file").or_else(|| h.get("datafile")) {
        Some(name) => {
            if name.starts_with("LIST") || name.split_whitespace().count() > 1 {
                return Err(invalid(
                    file,
                    format!("'data file: {name}': brainshift reads one detached data file"),
                ));
            }
            let path = file.parent().unwrap_or(Path::new(".")).join(name);
            let b = std::fs::read(&path).map_err(|e| {
                io(&path, format!("the data file named by {} ('data file'): {e}", file.display()))
            })?;
            (path, b)
        }
        None => (file.to_path_buf(), bytes[h.data_offset..].to_vec()),
    };
    let mut data = raw_bytes.as_slice();
    let line_skip: usize = h
        .get("line skip")
        .map_or(Ok(0), |s| s.parse())
        .map_err(|_| invalid(file, "'line skip' is not a whole number"))?;
    for _ in 0..line_skip {
        let n = data.iter().position(|&b| b == b'\n').ok_or_else(|| {
            invalid(&data_file, "'line skip' skips past the end of the data (truncated data)")
        })?;
        data = &data[n + 1..];
    }
    let byte_skip: i64 = h
        .get("byte skip")
        .map_or(Ok(0), |s| s.parse())
        .map_err(|_| invalid(file, "'byte skip' is not a whole number"))?;
    let decompressed;
    if gzip {
        let mut d = flate2::read::MultiGzDecoder::new(data);
        let mut out = Vec::with_capacity(bytes_needed as usize);
        d.by_ref().take(bytes_needed + 1).read_to_end(&mut out).map_err(|e| {
            invalid(
                &data_file,
                format!(
                    "the gzip data ('encoding: gzip') cannot be decompressed: {e} (a truncated \
                     or corrupt file; copy it again)"
                ),
            )
        })?;
        decompressed = out;
        data = &decompressed;
    }
    let data = if byte_skip == -1 {
        // The data are the last bytes of the file (raw only, per the NRRD format).
        let start = data
            .len()
            .checked_sub(bytes_needed as usize)
            .ok_or_else(|| truncated(&data_file, data.len(), bytes_needed))?;
        &data[start..]
    } else if byte_skip >= 0 {
        data.get(byte_skip as usize..).unwrap_or(&[])
    } else {
        return Err(invalid(file, format!("'byte skip: {byte_skip}' must be -1 or ≥ 0")));
    };
    if (data.len() as u64) < bytes_needed {
        return Err(truncated(&data_file, data.len(), bytes_needed));
    }
    let values: Vec<f64> = data[..bytes_needed as usize]
        .chunks_exact(scalar.size())
        .map(|b| scalar.value(b, big))
        .collect();
    if let Some(n) = values.iter().position(|v| !v.is_finite()) {
        return Err(invalid(file, format!("voxel {n} is {} (not a finite number)", values[n])));
    }
    Ok(Decoded { grid, values })
}

fn truncated(file: &Path, have: usize, need: u64) -> ImageError {
    invalid(
        file,
        format!(
            "the voxel data are truncated: {have} bytes for the {need} that 'sizes' and 'type' \
             declare; copy the file again"
        ),
    )
}

/// The world map of the header, in RAS mm.
fn grid_of(
    file: &Path,
    h: &Header,
    dim: usize,
    lead: usize,
    spatial: [usize; 3],
) -> Result<Grid, ImageError> {
    let space = match h.get("space") {
        Some(s) => match s.to_ascii_lowercase().as_str() {
            "left-posterior-superior" | "lps" => Space::Lps,
            "right-anterior-superior" | "ras" => Space::Ras,
            other => {
                return Err(invalid(
                    file,
                    format!(
                        "'space: {other}' is not an anatomical frame brainshift can place on the \
                         patient (left-posterior-superior or right-anterior-superior)"
                    ),
                ));
            }
        },
        None => {
            let hint = if h.get("space dimension").is_some() {
                "it has 'space dimension' but no anatomical 'space'"
            } else {
                "no 'space' field"
            };
            return Err(invalid(
                file,
                format!(
                    "{hint}: the image has no anatomical frame, and a mesh made from it could \
                     not be placed on the patient; add 'space: left-posterior-superior' (or \
                     re-save it from 3D Slicer)"
                ),
            ));
        }
    };
    if let Some(sd) = h.get("space dimension")
        && sd.trim() != "3"
    {
        return Err(invalid(
            file,
            format!("'space dimension: {sd}' contradicts 'space' (a 3-D anatomical frame)"),
        ));
    }
    let dirs_text = h.require(file, "space directions", "the voxel axes in mm")?;
    let dirs = direction_list(dirs_text);
    if dirs.len() != dim {
        return Err(invalid(
            file,
            format!(
                "'space directions' lists {} axes but 'dimension' is {dim}; one vector (or none) \
                 per axis",
                dirs.len()
            ),
        ));
    }
    let mut cols = [[0.0; 3]; 3];
    for (a, d) in dirs.iter().enumerate() {
        let v = vector(file, "space directions", d)?;
        match (a < lead, v) {
            (true, None) => {}
            (true, Some(_)) => {
                return Err(invalid(
                    file,
                    "'space directions': the non-spatial first axis must be 'none'",
                ));
            }
            (false, Some(v)) => cols[a - lead] = v,
            (false, None) => {
                return Err(invalid(
                    file,
                    format!("'space directions': spatial axis {} is 'none'", a - lead + 1),
                ));
            }
        }
    }
    let origin = match h.get("space origin") {
        Some(o) => vector(file, "space origin", o)?
            .ok_or_else(|| invalid(file, "'space origin' is none"))?,
        None => [0.0; 3],
    };
    let scale = match h.get("space units") {
        None => 1.0,
        Some(u) => {
            let units: Vec<&str> = u.split_whitespace().map(|s| s.trim_matches('"')).collect();
            let first = units.first().copied().unwrap_or("mm");
            if units.iter().any(|&x| x != first) {
                return Err(invalid(
                    file,
                    format!("'space units: {u}': the axes have different units"),
                ));
            }
            match first {
                "mm" | "" => 1.0,
                "m" => 1000.0,
                "um" | "µm" => 1e-3,
                "cm" => 10.0,
                other => {
                    return Err(invalid(
                        file,
                        format!("'space units: {other}' is not a length unit (mm, m, cm, um)"),
                    ));
                }
            }
        }
    };
    let flip = |r: usize| if space == Space::Lps && r < 2 { -1.0 } else { 1.0 };
    let mut m = Matrix4::identity();
    for r in 0..3 {
        for c in 0..3 {
            m[(r, c)] = flip(r) * cols[c][r] * scale;
        }
        m[(r, 3)] = flip(r) * origin[r] * scale;
    }
    Grid::new(spatial, m).map_err(|e| invalid(file, format!("'space directions': {e}")))
}

/// Reads a 3-D scalar NRRD image: values in float32, grid in RAS mm.
pub fn read_image(file: &Path) -> Result<Volume<f32>, ImageError> {
    let d = decode(file)?;
    Ok(Volume { grid: d.grid, data: d.values.into_iter().map(|v| v as f32).collect() })
}

/// Reads a NRRD labelmap (or a one-layer Slicer segmentation, `.seg.nrrd`): every voxel a
/// non-negative integer.
pub fn read_labels(file: &Path) -> Result<Volume<u32>, ImageError> {
    let d = decode(file)?;
    let [nx, ny, _] = d.grid.dims();
    let mut data = Vec::with_capacity(d.values.len());
    for (n, &v) in d.values.iter().enumerate() {
        if v < 0.0 || v.fract() != 0.0 || v > u32::MAX as f64 {
            return Err(invalid(
                file,
                format!(
                    "not a labelmap: voxel ({}, {}, {}) has the value {v}, and labels are \
                     non-negative integers; pass the segmentation, not an intensity image",
                    n % nx,
                    (n / nx) % ny,
                    n / (nx * ny)
                ),
            ));
        }
        data.push(v as u32);
    }
    Ok(Volume { grid: d.grid, data })
}

/// The header lines of a grid in LPS: space, sizes' spatial part, directions, origin.
fn lps_geometry(grid: &Grid) -> (String, String) {
    let m = grid.voxel_to_world();
    let flip = |r: usize| if r < 2 { -1.0 } else { 1.0 };
    let fmt = |v: [f64; 3]| format!("({},{},{})", v[0], v[1], v[2]);
    let dirs =
        (0..3).map(|c| fmt([0, 1, 2].map(|r| flip(r) * m[(r, c)]))).collect::<Vec<_>>().join(" ");
    let origin = fmt([0, 1, 2].map(|r| flip(r) * m[(r, 3)]));
    (dirs, origin)
}

/// Writes `header` and the gzip of `raw` atomically.
fn write_nrrd(file: &Path, header: &str, raw: &[u8]) -> Result<(), ImageError> {
    let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    z.write_all(raw).map_err(|e| io(file, e.to_string()))?;
    let compressed = z.finish().map_err(|e| io(file, e.to_string()))?;
    bs_atomic::write_atomic(file, |f| {
        f.write_all(header.as_bytes())?;
        f.write_all(&compressed)
    })
    .map_err(|e| io(file, format!("could not write: {e}")))
}

fn scalar_header(grid: &Grid, ty: &str) -> String {
    let [nx, ny, nz] = grid.dims();
    let (dirs, origin) = lps_geometry(grid);
    format!(
        "NRRD0004\n# written by brainshift\ntype: {ty}\ndimension: 3\nspace: left-posterior-superior\n\
         sizes: {nx} {ny} {nz}\nspace directions: {dirs}\nkinds: domain domain domain\n\
         endian: little\nencoding: gzip\nspace origin: {origin}\n\n"
    )
}

/// Writes a float32 image (gzip, LPS), atomically.
pub fn write_image(file: &Path, volume: &Volume<f32>) -> Result<(), ImageError> {
    let raw: Vec<u8> = volume.data.iter().flat_map(|v| v.to_le_bytes()).collect();
    write_nrrd(file, &scalar_header(&volume.grid, "float"), &raw)
}

/// Writes a labelmap (int32, gzip, LPS), atomically.
pub fn write_labels(file: &Path, volume: &Volume<u32>) -> Result<(), ImageError> {
    let raw: Vec<u8> =
        volume.data.iter().flat_map(|&v| (v.min(i32::MAX as u32) as i32).to_le_bytes()).collect();
    write_nrrd(file, &scalar_header(&volume.grid, "int"), &raw)
}

/// Writes a displacement field given in RAS (as brainshift holds it) as a vector NRRD in
/// LPS: `kinds: vector domain domain domain`, float32 vectors first (x, y, z per voxel),
/// gzip; atomically. ITK reads it as a vector image (a displacement field in SimpleITK),
/// 3D Slicer as a transform.
pub fn write_displacement(
    file: &Path,
    grid: &Grid,
    vectors_ras: &[[f32; 3]],
) -> Result<(), ImageError> {
    if vectors_ras.len() != grid.len() {
        return Err(io(file, format!("{} vectors for {} voxels", vectors_ras.len(), grid.len())));
    }
    let [nx, ny, nz] = grid.dims();
    let (dirs, origin) = lps_geometry(grid);
    let header = format!(
        "NRRD0004\n# written by brainshift: a displacement field (ITK convention: output point \
         y samples the input at y + d(y)), LPS, mm\ntype: float\ndimension: 4\n\
         space: left-posterior-superior\nsizes: 3 {nx} {ny} {nz}\n\
         space directions: none {dirs}\nkinds: vector domain domain domain\nendian: little\n\
         encoding: gzip\nspace origin: {origin}\n\n"
    );
    let raw: Vec<u8> = vectors_ras
        .iter()
        .flat_map(|v| [-v[0], -v[1], v[2]])
        .flat_map(|c| c.to_le_bytes())
        .collect();
    write_nrrd(file, &header, &raw)
}
