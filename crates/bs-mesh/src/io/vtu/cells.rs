//! The cell model shared by the VTU and legacy VTK readers and writers.

use std::io;
use std::path::Path;

use nalgebra::Point3;

use crate::io::{Field, Fields, Location, ParseError};
use crate::{Element, Mesh};

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
