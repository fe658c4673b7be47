//! Free functions: reading a mesh, measuring gaps to a skull.

use std::path::PathBuf;

use bs_contact::{Handler, MasterSurface, PaperParams};
use bs_mesh::Point3;
use bs_scene::scene::Algorithm;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{f64_rows, raise, skull_of};

/// Reads a volume mesh: a dict with nodes (float64 n×3), node_ids, elements (int64 m×4 for
/// tets, m×8 for hexes; a mixed mesh pads tets with -1), element_ids, and node_sets /
/// element_sets (dicts of 0-based index arrays).
#[pyfunction]
pub(crate) fn read_mesh<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let mesh = py
        .detach(|| bs_mesh::io::read_mesh(&path))
        .map_err(|e| raise(py, "Read", e.to_string(), false))?;
    let n = mesh.nodes.len();
    let nodes =
        Array2::from_shape_vec((n, 3), mesh.nodes.iter().flat_map(|p| [p.x, p.y, p.z]).collect())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let width = mesh.elements.iter().map(|e| e.nodes().len()).max().unwrap_or(4);
    let mut cells = Vec::with_capacity(mesh.elements.len() * width);
    for e in &mesh.elements {
        cells.extend(e.nodes().iter().map(|&i| i as i64));
        cells.extend(std::iter::repeat_n(-1, width - e.nodes().len()));
    }
    let elements = Array2::from_shape_vec((mesh.elements.len(), width), cells)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let d = PyDict::new(py);
    d.set_item("nodes", nodes.into_pyarray(py))?;
    d.set_item("node_ids", PyArray1::from_vec(py, mesh.node_ids.clone()))?;
    d.set_item("elements", elements.into_pyarray(py))?;
    d.set_item("element_ids", PyArray1::from_vec(py, mesh.element_ids.clone()))?;
    for (key, sets) in [("node_sets", &mesh.node_sets), ("element_sets", &mesh.element_sets)] {
        let s = PyDict::new(py);
        for (name, members) in sets {
            let v: Vec<i64> = members.iter().map(|&i| i as i64).collect();
            s.set_item(name, PyArray1::from_vec(py, v))?;
        }
        d.set_item(key, s)?;
    }
    Ok(d)
}

/// Brain–skull gap of `points` (n×3) to a skull given as a path or `(vertices,
/// triangles)`, as `brainshift gap --points`: a dict of signed_distance (positive =
/// inside), closest (n×3) and outside (bool).
#[pyfunction]
#[pyo3(signature = (skull, points, algorithm="paper"))]
pub(crate) fn gap<'py>(
    py: Python<'py>,
    skull: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
    algorithm: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let algorithm = match algorithm {
        "paper" => Algorithm::Paper,
        "coherent" => Algorithm::Coherent,
        "parry" => Algorithm::Parry,
        "brute-force" => Algorithm::BruteForce,
        other => {
            return Err(PyValueError::new_err(format!(
                "algorithm '{other}': use paper, coherent, parry or brute-force"
            )));
        }
    };
    let (surface, path) = skull_of(py, skull)?;
    let pts: Vec<Point3<f64>> = f64_rows(py, points, 3, "points")?
        .into_iter()
        .map(|p| Point3::new(p[0], p[1], p[2]))
        .collect();
    let sk = path.display().to_string();
    let rows = py
        .detach(|| -> Result<_, String> {
            let master = std::sync::Arc::new(
                MasterSurface::new(&surface).map_err(|e| format!("{sk}: {e}"))?,
            );
            let mut handler =
                Handler::from_master(algorithm, master.clone(), PaperParams::default())
                    .map_err(|e| format!("{sk}: {e}"))?;
            Ok(bs_contact::gap(&mut handler, &master, &pts))
        })
        .map_err(|m| raise(py, "Skull", m, false))?;
    let n = rows.len();
    let d = PyDict::new(py);
    d.set_item(
        "signed_distance",
        PyArray1::from_vec(py, rows.iter().map(|r| r.signed_distance).collect()),
    )?;
    let closest = Array2::from_shape_vec(
        (n, 3),
        rows.iter().flat_map(|r| [r.closest.x, r.closest.y, r.closest.z]).collect(),
    )
    .map_err(|e| PyValueError::new_err(e.to_string()))?;
    d.set_item("closest", closest.into_pyarray(py))?;
    d.set_item("outside", PyArray1::from_vec(py, rows.iter().map(|r| r.outside).collect()))?;
    Ok(d)
}
