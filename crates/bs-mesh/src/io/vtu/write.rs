//! The VTU writer.

use std::io::{self, Write};

use base64::Engine;

use super::Encoding;
use super::cells::check_for_write;
use crate::Mesh;
use crate::io::Fields;

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
