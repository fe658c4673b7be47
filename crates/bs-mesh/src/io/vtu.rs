//! VTK XML unstructured grids (`.vtu`).
//!
//! Writer: `header_type="UInt64"`, little-endian, points `Float64`, connectivity and offsets
//! `Int64`, types `UInt8` (10 tetrahedron, 12 hexahedron). Point data: every point [`Field`]
//! (`Float64`), plus `node_id` (`Int64`, [`Mesh::node_ids`]) and one `UInt8` array
//! `nset:<NAME>` per node set (1 = member). Cell data likewise with `element_id` and
//! `elset:<NAME>`. [`Encoding::Inline`] writes `format="binary"` base64 data arrays;
//! [`Encoding::Appended`] writes them into `<AppendedData encoding="base64">`, each array's
//! block being base64 of (header + data) with its offset counted in the encoded stream.
//!
//! Reader: ASCII, inline binary and appended (base64 or raw) data, `UInt32` or `UInt64`
//! headers, zlib-compressed data (`vtkZLibDataCompressor`, the default of ParaView and
//! meshio), every integer and float array type. The `node_id`, `element_id`, `nset:` and
//! `elset:` arrays are mapped back, so write→read round trips exactly. Without `node_id` /
//! `element_id`, ids are 0-based positions (VTK convention; a cell's id is its index among
//! all cells of the file). Surface and line cells are skipped; voxels become hexahedra;
//! other volume cells (wedges, quadratic elements…) are errors naming the cell.

use std::collections::HashMap;
use std::io::{self, Write};
use std::path::Path;

use base64::Engine;
use nalgebra::Point3;
use quick_xml::events::{BytesStart, Event};

use super::{Field, Fields, Location, ParseError};
use crate::{Element, Mesh};

/// How VTU data arrays are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// Base64 binary inside each DataArray (`format="binary"`).
    Inline,
    /// Base64 binary in an `<AppendedData encoding="base64">` section (`format="appended"`).
    Appended,
}

// ---------------------------------------------------------------------------------------
// Shared with the legacy VTK reader: typed arrays and the assembly of a Mesh from VTK cells.
// ---------------------------------------------------------------------------------------

/// Values of a data array: floats, or integers (unsigned 64-bit values are stored by bits).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Data {
    /// Float32 / Float64 values.
    F(Vec<f64>),
    /// Integer values; `UInt64` values above `i64::MAX` keep their bits.
    I(Vec<i64>),
}

impl Data {
    pub(crate) fn len(&self) -> usize {
        match self {
            Data::F(v) => v.len(),
            Data::I(v) => v.len(),
        }
    }

    fn to_f64(&self) -> Vec<f64> {
        match self {
            Data::F(v) => v.clone(),
            Data::I(v) => v.iter().map(|&x| x as f64).collect(),
        }
    }

    fn get_f64(&self, i: usize) -> f64 {
        match self {
            Data::F(v) => v[i],
            Data::I(v) => v[i] as f64,
        }
    }

    /// Integer view (floats must be integral).
    fn to_ints(&self) -> Option<Vec<i64>> {
        match self {
            Data::I(v) => Some(v.clone()),
            Data::F(v) => v
                .iter()
                .map(|&x| (x.fract() == 0.0 && x.abs() < 9.0e18).then_some(x as i64))
                .collect(),
        }
    }
}

/// A named point or cell array as read from a file.
#[derive(Debug, Clone)]
pub(crate) struct Array {
    pub(crate) name: String,
    pub(crate) ncomp: usize,
    pub(crate) data: Data,
    pub(crate) loc: Location,
}

/// The cells of a VTK unstructured grid: `offsets[i]` is the end of cell `i` in
/// `connectivity` (VTU convention).
#[derive(Debug, Clone, Default)]
pub(crate) struct Cells {
    pub(crate) connectivity: Vec<i64>,
    pub(crate) offsets: Vec<i64>,
    pub(crate) types: Vec<i64>,
    pub(crate) loc: Option<Location>,
}

enum CellAction {
    Keep(crate::ElementKind),
    Voxel,
    Skip,
}

fn vtk_cell_name(t: i64) -> &'static str {
    match t {
        13 => "wedge",
        14 => "pyramid",
        15 => "pentagonal prism",
        16 => "hexagonal prism",
        24 => "quadratic tetrahedron",
        25 => "quadratic hexahedron",
        26 => "quadratic wedge",
        27 => "quadratic pyramid",
        29 => "triquadratic hexahedron",
        32 => "biquadratic-quadratic wedge",
        33 => "biquadratic-quadratic hexahedron",
        42 => "polyhedron",
        71 => "Lagrange tetrahedron",
        72 => "Lagrange hexahedron",
        73 => "Lagrange wedge",
        74 => "Lagrange pyramid",
        78 => "Bezier tetrahedron",
        79 => "Bezier hexahedron",
        80 => "Bezier wedge",
        81 => "Bezier pyramid",
        _ => "unknown cell type",
    }
}

fn cell_action(i: usize, t: i64) -> Result<CellAction, String> {
    use crate::ElementKind::{Hex8, Tet4};
    Ok(match t {
        10 => CellAction::Keep(Tet4),
        12 => CellAction::Keep(Hex8),
        11 => CellAction::Voxel,
        // Vertices, lines, triangles, strips, polygons, pixels, quads and their quadratic,
        // Lagrange and Bezier versions: boundary/annotation cells, not volume elements.
        1..=9 | 21 | 22 | 23 | 28 | 30 | 31 | 34 | 35 | 36 | 68 | 69 | 70 | 75 | 76 | 77 => {
            CellAction::Skip
        }
        24..=27 | 29 | 32 | 33 | 71..=74 | 78..=81 => {
            return Err(format!(
                "cell {i} is a {} (VTK type {t}); brainshift needs linear tetrahedra (VTK 10) \
                 or hexahedra (VTK 12): re-mesh with first-order elements (gmsh: \
                 `-order 1`) or drop the mid-side nodes",
                vtk_cell_name(t)
            ));
        }
        _ => {
            return Err(format!(
                "cell {i} is a {} (VTK type {t}); brainshift supports only tetrahedra (VTK 10) \
                 and hexahedra (VTK 12, or voxels 11): convert the mesh to T4 or H8 elements",
                vtk_cell_name(t)
            ));
        }
    })
}

/// The `npoints` points of a decoded points array (three components each).
pub(crate) fn points_of(
    file: &Path,
    npoints: usize,
    points: &Array,
) -> Result<Vec<Point3<f64>>, ParseError> {
    if Some(points.data.len()) != npoints.checked_mul(3) || points.ncomp != 3 {
        return Err(ParseError::new(
            file,
            points.loc,
            format!(
                "points: expected {npoints} points with 3 components ({} values), found {} \
                 values with {} components",
                3 * npoints as u128,
                points.data.len(),
                points.ncomp
            ),
        ));
    }
    Ok((0..npoints)
        .map(|i| {
            let c = |k| points.data.get_f64(3 * i + k);
            Point3::new(c(0), c(1), c(2))
        })
        .collect())
}

/// Builds the mesh and fields from decoded VTK arrays, mapping `node_id`, `element_id`,
/// `nset:` and `elset:` arrays back.
pub(crate) fn assemble(
    file: &Path,
    npoints: usize,
    points: &Array,
    cells: &Cells,
    point_arrays: Vec<Array>,
    cell_arrays: Vec<Array>,
) -> Result<(Mesh, Fields), ParseError> {
    let err = |loc: Location, msg: String| ParseError::new(file, loc, msg);
    let nodes = points_of(file, npoints, points)?;
    let cloc = cells.loc.unwrap_or(Location::File);
    let ncells = cells.types.len();
    if cells.offsets.len() != ncells {
        return Err(err(
            cloc,
            format!(
                "cells: {} cell types but {} offsets; the two arrays must have one entry per cell",
                ncells,
                cells.offsets.len()
            ),
        ));
    }
    let mut elements = Vec::with_capacity(ncells);
    let mut kept = Vec::with_capacity(ncells);
    let mut start = 0i64;
    for (i, (&t, &end)) in cells.types.iter().zip(&cells.offsets).enumerate() {
        if end < start || end as u64 > cells.connectivity.len() as u64 {
            return Err(err(
                cloc,
                format!(
                    "cell {i}: offset {end} is out of order or beyond the {} connectivity entries",
                    cells.connectivity.len()
                ),
            ));
        }
        let conn = &cells.connectivity[start as usize..end as usize];
        start = end;
        let action = cell_action(i, t).map_err(|m| err(cloc, m))?;
        let kind = match action {
            CellAction::Skip => continue,
            CellAction::Keep(k) => k,
            CellAction::Voxel => crate::ElementKind::Hex8,
        };
        if conn.len() != kind.node_count() {
            return Err(err(
                cloc,
                format!(
                    "cell {i} (VTK type {t}) has {} nodes; a {} has {}",
                    conn.len(),
                    kind.name(),
                    kind.node_count()
                ),
            ));
        }
        let mut n = [0usize; 8];
        for (k, &c) in conn.iter().enumerate() {
            if c < 0 || c as u64 >= npoints as u64 {
                return Err(err(
                    cloc,
                    format!("cell {i} refers to point {c}, but the file has {npoints} points"),
                ));
            }
            n[k] = c as usize;
        }
        let e = match action {
            CellAction::Voxel => Element::hex8([n[0], n[1], n[3], n[2], n[4], n[5], n[7], n[6]]),
            _ => Element::from_nodes(&n[..kind.node_count()]).expect("4 or 8 nodes"),
        };
        elements.push(e);
        kept.push(i);
    }
    let mut mesh = Mesh {
        nodes,
        node_ids: (0..npoints as u64).collect(),
        element_ids: kept.iter().map(|&i| i as u64).collect(),
        elements,
        ..Default::default()
    };
    let mut fields = Fields::default();
    let check = |a: &Array, count: usize, what: &str| -> Result<(), ParseError> {
        if a.ncomp == 0 || Some(a.data.len()) != a.ncomp.checked_mul(count) {
            return Err(err(
                a.loc,
                format!(
                    "{what} array '{}' has {} values with {} components; expected {} tuples \
                     (one per {what})",
                    a.name,
                    a.data.len(),
                    a.ncomp,
                    count
                ),
            ));
        }
        Ok(())
    };
    let ints = |a: &Array| -> Result<Vec<i64>, ParseError> {
        if a.ncomp != 1 {
            return Err(err(a.loc, format!("array '{}' must have 1 component", a.name)));
        }
        a.data.to_ints().ok_or_else(|| err(a.loc, format!("array '{}' must hold integers", a.name)))
    };
    for a in point_arrays {
        check(&a, npoints, "point")?;
        if a.name == "node_id" {
            mesh.node_ids = ints(&a)?.into_iter().map(|x| x as u64).collect();
        } else if let Some(set) = a.name.strip_prefix("nset:") {
            let v = ints(&a)?;
            mesh.node_sets.insert(set.to_string(), (0..npoints).filter(|&i| v[i] != 0).collect());
        } else {
            fields.point.push(Field::new(a.name, a.ncomp, a.data.to_f64()));
        }
    }
    for a in cell_arrays {
        check(&a, ncells, "cell")?;
        if a.name == "element_id" {
            let v = ints(&a)?;
            mesh.element_ids = kept.iter().map(|&i| v[i] as u64).collect();
        } else if let Some(set) = a.name.strip_prefix("elset:") {
            let v = ints(&a)?;
            let members = kept.iter().enumerate().filter(|&(_, &i)| v[i] != 0).map(|(k, _)| k);
            mesh.element_sets.insert(set.to_string(), members.collect());
        } else {
            let c = a.ncomp;
            let mut values = Vec::with_capacity(kept.len() * c);
            for &i in &kept {
                values.extend((0..c).map(|k| a.data.get_f64(i * c + k)));
            }
            fields.cell.push(Field::new(a.name, c, values));
        }
    }
    Ok((mesh, fields))
}

/// Checks what the writers need: consistent ids, in-range indices, field sizes and names.
pub(crate) fn check_for_write(mesh: &Mesh, fields: &Fields) -> io::Result<()> {
    let bad = |m: String| Err(io::Error::new(io::ErrorKind::InvalidInput, m));
    let (nn, ne) = (mesh.nodes.len(), mesh.elements.len());
    if mesh.node_ids.len() != nn || mesh.element_ids.len() != ne {
        return bad(format!(
            "mesh has {nn} nodes with {} ids and {ne} elements with {} ids",
            mesh.node_ids.len(),
            mesh.element_ids.len()
        ));
    }
    if let Some(e) = mesh.elements.iter().position(|e| e.nodes().iter().any(|&n| n >= nn)) {
        return bad(format!(
            "element {} refers to a node beyond the {nn} nodes",
            mesh.element_ids[e]
        ));
    }
    for (name, s) in &mesh.node_sets {
        if s.iter().any(|&i| i >= nn) {
            return bad(format!("node set '{name}' holds an index beyond the {nn} nodes"));
        }
    }
    for (name, s) in &mesh.element_sets {
        if s.iter().any(|&i| i >= ne) {
            return bad(format!("element set '{name}' holds an index beyond the {ne} elements"));
        }
    }
    for (list, count, what, id, set) in [
        (&fields.point, nn, "point", "node_id", "nset:"),
        (&fields.cell, ne, "cell", "element_id", "elset:"),
    ] {
        for f in list {
            if f.components == 0 || f.values.len() != f.components * count {
                return bad(format!(
                    "{what} field '{}' has {} values with {} components; {count} tuples are needed",
                    f.name,
                    f.values.len(),
                    f.components
                ));
            }
            if f.name.is_empty() || f.name == id || f.name.starts_with(set) {
                return bad(format!(
                    "{what} field name '{}' is empty or reserved ('{id}' and '{set}…' hold ids and sets)",
                    f.name
                ));
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------------------

struct OutArray {
    name: String,
    ty: &'static str,
    ncomp: usize,
    bytes: Vec<u8>,
}

fn f64_bytes(v: impl Iterator<Item = f64>) -> Vec<u8> {
    v.flat_map(f64::to_le_bytes).collect()
}

fn i64_bytes(v: impl Iterator<Item = i64>) -> Vec<u8> {
    v.flat_map(i64::to_le_bytes).collect()
}

fn membership(n: usize, members: &[usize]) -> Vec<u8> {
    let mut v = vec![0u8; n];
    for &i in members {
        v[i] = 1;
    }
    v
}

pub(crate) fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if (c as u32) < 0x20 => out.push_str(&format!("&#{};", c as u32)),
            c => out.push(c),
        }
    }
    out
}

/// Writes a VTU file (see the module documentation for the layout).
/// `fields.field_data` become one `<FieldData>` `String` array each (the characters' codes
/// and a terminating 0, as VTK writes them), e.g. `SPACE` = `RAS`, which 3D Slicer reads as
/// the coordinate frame.
pub fn write(w: &mut dyn Write, mesh: &Mesh, fields: &Fields, enc: Encoding) -> io::Result<()> {
    check_for_write(mesh, fields)?;
    let (nn, ne) = (mesh.nodes.len(), mesh.elements.len());
    let mut point = Vec::new();
    for f in &fields.point {
        let bytes = f64_bytes(f.values.iter().copied());
        point.push(OutArray { name: f.name.clone(), ty: "Float64", ncomp: f.components, bytes });
    }
    let ids = i64_bytes(mesh.node_ids.iter().map(|&i| i as i64));
    point.push(OutArray { name: "node_id".into(), ty: "Int64", ncomp: 1, bytes: ids });
    for (name, s) in &mesh.node_sets {
        let bytes = membership(nn, s);
        point.push(OutArray { name: format!("nset:{name}"), ty: "UInt8", ncomp: 1, bytes });
    }
    let mut cell = Vec::new();
    for f in &fields.cell {
        let bytes = f64_bytes(f.values.iter().copied());
        cell.push(OutArray { name: f.name.clone(), ty: "Float64", ncomp: f.components, bytes });
    }
    let ids = i64_bytes(mesh.element_ids.iter().map(|&i| i as i64));
    cell.push(OutArray { name: "element_id".into(), ty: "Int64", ncomp: 1, bytes: ids });
    for (name, s) in &mesh.element_sets {
        let bytes = membership(ne, s);
        cell.push(OutArray { name: format!("elset:{name}"), ty: "UInt8", ncomp: 1, bytes });
    }
    let coords = f64_bytes(mesh.nodes.iter().flat_map(|p| [p.x, p.y, p.z]));
    let points = vec![OutArray { name: "Points".into(), ty: "Float64", ncomp: 3, bytes: coords }];
    let conn = i64_bytes(mesh.elements.iter().flat_map(|e| e.nodes().iter().map(|&n| n as i64)));
    let mut end = 0i64;
    let offsets = i64_bytes(mesh.elements.iter().map(|e| {
        end += e.nodes().len() as i64;
        end
    }));
    let types: Vec<u8> = mesh
        .elements
        .iter()
        .map(|e| match e.kind() {
            crate::ElementKind::Tet4 => 10,
            crate::ElementKind::Hex8 => 12,
        })
        .collect();
    let cells = vec![
        OutArray { name: "connectivity".into(), ty: "Int64", ncomp: 1, bytes: conn },
        OutArray { name: "offsets".into(), ty: "Int64", ncomp: 1, bytes: offsets },
        OutArray { name: "types".into(), ty: "UInt8", ncomp: 1, bytes: types },
    ];

    let b64 = base64::engine::general_purpose::STANDARD;
    let block = |a: &OutArray| {
        let mut raw = Vec::with_capacity(8 + a.bytes.len());
        raw.extend_from_slice(&(a.bytes.len() as u64).to_le_bytes());
        raw.extend_from_slice(&a.bytes);
        b64.encode(raw)
    };
    let mut appended = String::new();
    let mut array = |w: &mut dyn Write, a: &OutArray| -> io::Result<()> {
        let head = format!(
            "<DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\"",
            a.ty,
            xml_escape(&a.name),
            a.ncomp
        );
        match enc {
            Encoding::Inline => {
                writeln!(w, "{head} format=\"binary\">\n{}\n</DataArray>", block(a))
            }
            Encoding::Appended => {
                writeln!(w, "{head} format=\"appended\" offset=\"{}\"/>", appended.len())?;
                appended.push_str(&block(a));
                Ok(())
            }
        }
    };
    writeln!(w, "<?xml version=\"1.0\"?>")?;
    writeln!(
        w,
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\">"
    )?;
    writeln!(w, "<!-- written by brainshift -->")?;
    writeln!(w, "<UnstructuredGrid>")?;
    if !fields.field_data.is_empty() {
        // VTK's String arrays: the bytes as integers, each string ended by a 0.
        writeln!(w, "<FieldData>")?;
        for (name, value) in &fields.field_data {
            let bytes: Vec<String> = value.bytes().chain([0]).map(|b| b.to_string()).collect();
            writeln!(
                w,
                "<DataArray type=\"String\" Name=\"{}\" NumberOfTuples=\"1\" \
                 format=\"ascii\">\n{}\n</DataArray>",
                xml_escape(name),
                bytes.join(" ")
            )?;
        }
        writeln!(w, "</FieldData>")?;
    }
    writeln!(w, "<Piece NumberOfPoints=\"{nn}\" NumberOfCells=\"{ne}\">")?;
    for (tag, list) in
        [("PointData", &point), ("CellData", &cell), ("Points", &points), ("Cells", &cells)]
    {
        writeln!(w, "<{tag}>")?;
        for a in list {
            array(w, a)?;
        }
        writeln!(w, "</{tag}>")?;
    }
    writeln!(w, "</Piece>")?;
    writeln!(w, "</UnstructuredGrid>")?;
    if enc == Encoding::Appended {
        writeln!(w, "<AppendedData encoding=\"base64\">")?;
        writeln!(w, "_{appended}")?;
        writeln!(w, "</AppendedData>")?;
    }
    writeln!(w, "</VTKFile>")
}

// ---------------------------------------------------------------------------------------
// Reader
// ---------------------------------------------------------------------------------------

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
    let err = |pos: usize, msg: String| ParseError::new(file, Location::Byte(pos), msg);
    // The appended section is not XML (raw binary may hold anything): parse only the markup
    // before it and remember where its data starts.
    let mut xml: Vec<u8>;
    let mut appended: Option<(String, &[u8])> = None;
    let xml_src: &[u8] = match find(bytes, b"<AppendedData") {
        Some(p) => {
            let q = p + bytes[p..]
                .iter()
                .position(|&b| b == b'>')
                .ok_or_else(|| err(p, "unterminated <AppendedData> tag".into()))?;
            let mut u = q + 1;
            while u < bytes.len() && bytes[u].is_ascii_whitespace() {
                u += 1;
            }
            if bytes.get(u) != Some(&b'_') {
                return Err(err(u, "appended data must start with '_'".into()));
            }
            let data_end =
                rfind(bytes, b"</AppendedData>").filter(|&e| e > u).unwrap_or(bytes.len());
            xml = bytes[..=q].to_vec();
            xml.extend_from_slice(b"</AppendedData></VTKFile>");
            appended = Some((String::new(), &bytes[u + 1..data_end]));
            &xml
        }
        None => bytes,
    };
    let mut reader = quick_xml::Reader::from_reader(xml_src);
    let mut stack: Vec<String> = Vec::new();
    let mut layout = Layout { header64: false, zlib: false };
    let mut piece: Option<(HashMap<String, String>, usize)> = None; // attributes, position
    let mut arrays: Vec<RawArray> = Vec::new();
    let mut open_array = false;
    let mut saw_vtkfile = false;
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
            "VTKFile" => {
                saw_vtkfile = true;
                if let Some(t) = at.get("type").filter(|t| *t != kind) {
                    let holds = match kind {
                        "UnstructuredGrid" => "only UnstructuredGrid (.vtu) holds a volume mesh",
                        _ => "only PolyData (.vtp) holds a point cloud or a surface here",
                    };
                    return Err(err(pos, format!("VTK file of type '{t}'; {holds}")));
                }
                if at.get("byte_order").is_some_and(|b| b == "BigEndian") {
                    return Err(err(
                        pos,
                        "big-endian VTU is not supported; save it little-endian".into(),
                    ));
                }
                layout.header64 = match at.get("header_type").map(String::as_str) {
                    None | Some("UInt32") => false,
                    Some("UInt64") => true,
                    Some(o) => {
                        return Err(err(pos, format!("header_type '{o}' is not UInt32 or UInt64")));
                    }
                };
                match at.get("compressor").map(String::as_str) {
                    None | Some("") => {}
                    Some("vtkZLibDataCompressor") => layout.zlib = true,
                    Some(o) => {
                        return Err(err(
                            pos,
                            format!(
                                "data compressed with {o} is not supported; save uncompressed or \
                                 with zlib (ParaView: Data Mode Binary, Compressor ZLib or None)"
                            ),
                        ));
                    }
                }
            }
            "Piece" => {
                if piece.is_some() {
                    return Err(err(pos, "VTK XML file with several pieces; merge them into one (ParaView: Merge Blocks) before use".into()));
                }
                piece = Some((at.clone(), pos));
            }
            "AppendedData" => {
                if let Some(a) = appended.as_mut() {
                    a.0 = at.get("encoding").cloned().unwrap_or_else(|| "raw".into());
                }
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
    if !saw_vtkfile {
        return Err(ParseError::new(
            file,
            Location::File,
            "no <VTKFile> element: not a VTK XML file",
        ));
    }
    let (piece_attrs, piece_pos) = piece.ok_or_else(|| {
        ParseError::new(
            file,
            Location::File,
            format!("no <Piece> element: the dataset is empty or not of type {kind}"),
        )
    })?;

    // Appended base64: an array's encoded block ends where the next one starts.
    let mut offsets: Vec<usize> = arrays
        .iter()
        .filter_map(|a| a.attrs.get("offset").and_then(|o| o.trim().parse().ok()))
        .collect();
    offsets.sort_unstable();
    offsets.dedup();

    let mut decoded = Vec::new();
    let mut field_data = Vec::new();
    for a in arrays {
        // Arrays outside the asked sections and the dataset's field data carry nothing the
        // caller needs.
        if a.section != "FieldData" && !sections.contains(&a.section.as_str()) {
            continue;
        }
        let ty = a.attrs.get("type").cloned().unwrap_or_default();
        if a.section == "FieldData" {
            // Dataset-level strings (e.g. SPACE) in ASCII; other field data is not used.
            let ascii = a.attrs.get("format").is_none_or(|f| f == "ascii");
            if ty == "String" && ascii {
                let text = String::from_utf8_lossy(&a.text);
                let bytes: Vec<u8> = text
                    .split_ascii_whitespace()
                    .map_while(|b| b.parse::<u8>().ok())
                    .take_while(|&b| b != 0)
                    .collect();
                let name = a.attrs.get("Name").cloned().unwrap_or_default();
                field_data.push((name, String::from_utf8_lossy(&bytes).into_owned()));
            }
            continue;
        }
        let fail = |m: String| {
            err(a.pos, format!("DataArray '{}': {m}", a.attrs.get("Name").map_or("", |s| s)))
        };
        type_size(&ty).ok_or_else(|| {
            fail(format!("type '{ty}' is not supported (use Float32/64, (U)Int8/16/32/64)"))
        })?;
        let format = a.attrs.get("format").map(String::as_str).unwrap_or("ascii");
        let data = match format {
            "ascii" => {
                let text = std::str::from_utf8(&a.text)
                    .map_err(|_| fail("ASCII data is not text".into()))?;
                parse_ascii(ty.starts_with("Float"), text).map_err(fail)?
            }
            "binary" => {
                let raw = b64_decode(&a.text).map_err(fail)?;
                convert_le(&ty, &layout.block(&raw).map_err(fail)?).map_err(fail)?
            }
            "appended" => {
                let (encoding, data) = appended.as_ref().ok_or_else(|| {
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
                    return Err(fail(format!(
                        "appended encoding '{encoding}' is not raw or base64"
                    )));
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
        let loc = Location::Byte(a.pos);
        decoded.push((a.section, Array { name, ncomp, data, loc }));
    }
    Ok(XmlPiece { attrs: piece_attrs, pos: piece_pos, arrays: decoded, field_data })
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
