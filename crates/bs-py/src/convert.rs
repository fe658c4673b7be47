//! Errors as Python exceptions, arrays and arguments as brainshift types, thread pools and
//! progress callbacks: what every class and function of the bindings shares.

use std::collections::BTreeMap;
use std::path::PathBuf;

use bs_mesh::{Point3, TriSurface};
use bs_scene::SceneError;
use bs_sweep::SweepError;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::BrainshiftError;

/// The Python exception of a library error: OSError for a file that could not be written,
/// BrainshiftError (with `kind`) for everything brainshift refuses.
pub(crate) fn raise(py: Python<'_>, kind: &str, message: String, write: bool) -> PyErr {
    if write {
        return PyOSError::new_err(message);
    }
    let err = BrainshiftError::new_err(message);
    let _ = err.value(py).setattr("kind", kind);
    err
}

/// The Python exception of an image that cannot be read (BrainshiftError, kind "Image").
pub(crate) fn image_error(py: Python<'_>, e: bs_image::ImageError) -> PyErr {
    scene_err(py, bs_register::registration::image_error(e))
}

pub(crate) fn scene_err(py: Python<'_>, e: SceneError) -> PyErr {
    let write = matches!(e, SceneError::Write { .. });
    raise(py, e.kind(), e.to_string(), write)
}

pub(crate) fn sweep_err(py: Python<'_>, e: SweepError) -> PyErr {
    let write = matches!(e, SweepError::Write { .. });
    raise(py, e.kind(), e.to_string(), write)
}

/// Runs `f` on `threads` worker threads (the global pool, all cores, when `None`).
pub(crate) fn with_threads<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> T + Send,
) -> Result<T, String> {
    match threads {
        None => Ok(f()),
        Some(0) => Err("threads=0: give at least 1 worker thread (or None for all cores)".into()),
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| format!("cannot start {n} threads: {e}"))?;
            Ok(pool.install(f))
        }
    }
}

/// The solver observer of a Python `progress` callable: a dict per step or iteration (step,
/// load_factor, error_estimate, max_displacement, nodes_in_contact, and the linear iterations
/// and force evaluations so far), the GIL taken for
/// each call; the first exception the callable raises is kept in `error` (and later calls
/// skipped) to be raised when the solve ends.
pub(crate) fn observer<'a>(
    progress: Option<&'a Py<PyAny>>,
    error: &'a mut Option<PyErr>,
) -> impl FnMut(&bs_scene::Progress) + 'a {
    move |p| {
        let Some(cb) = progress else { return };
        if error.is_some() {
            return;
        }
        Python::attach(|py| {
            let call = || -> PyResult<()> {
                let d = PyDict::new(py);
                d.set_item("step", p.step)?;
                d.set_item("load_factor", p.load_factor)?;
                d.set_item("error_estimate", p.err)?;
                d.set_item("max_displacement", p.max_displacement)?;
                d.set_item("nodes_in_contact", p.contact.nodes_in_contact)?;
                d.set_item("linear_iterations", p.linear_iterations)?;
                d.set_item("force_evaluations", p.force_evaluations)?;
                cb.call1(py, (d,))?;
                Ok(())
            };
            if let Err(e) = call() {
                *error = Some(e);
            }
        });
    }
}

/// `json.loads(text)`.
pub(crate) fn from_json(py: Python<'_>, text: &str) -> PyResult<Py<PyAny>> {
    Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
}

/// A 2-D float64 array with `cols` columns from anything numpy accepts.
pub(crate) fn f64_rows<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    cols: usize,
    name: &str,
) -> PyResult<Vec<[f64; 3]>> {
    let arr = py.import("numpy")?.call_method1("ascontiguousarray", (obj, "float64"))?;
    let arr: PyReadonlyArray2<'py, f64> = arr.extract().map_err(|_| {
        PyValueError::new_err(format!("{name} must be a 2-D array of shape (n, {cols})"))
    })?;
    let view = arr.as_array();
    if view.ncols() != cols {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (n, {cols}), got {:?}",
            view.shape()
        )));
    }
    let mut out = Vec::with_capacity(view.nrows());
    for (i, r) in view.rows().into_iter().enumerate() {
        if r.iter().any(|x| !x.is_finite()) {
            return Err(PyValueError::new_err(format!("{name}[{i}] is not finite")));
        }
        out.push([r[0], r[1], r[2]]);
    }
    Ok(out)
}

/// A 2-D int64 array of 0-based indices below `bound`, rows of 4 or 8 (or exactly `cols`).
pub(crate) fn index_rows<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    cols: &[usize],
    bound: usize,
    name: &str,
) -> PyResult<Vec<Vec<usize>>> {
    let arr = py.import("numpy")?.call_method1("ascontiguousarray", (obj, "int64"))?;
    let shape_err = || {
        PyValueError::new_err(format!(
            "{name} must be a 2-D integer array with {} columns",
            cols.iter().map(usize::to_string).collect::<Vec<_>>().join(" or ")
        ))
    };
    let arr: PyReadonlyArray2<'py, i64> = arr.extract().map_err(|_| shape_err())?;
    let view = arr.as_array();
    if !cols.contains(&view.ncols()) {
        return Err(shape_err());
    }
    let mut out = Vec::with_capacity(view.nrows());
    for (i, r) in view.rows().into_iter().enumerate() {
        let mut row = Vec::with_capacity(r.len());
        for &x in r {
            match usize::try_from(x) {
                Ok(v) if v < bound => row.push(v),
                _ => {
                    return Err(PyValueError::new_err(format!(
                        "{name}[{i}] refers to index {x}, but there are {bound} (0-based indices)"
                    )));
                }
            }
        }
        out.push(row);
    }
    Ok(out)
}

/// Named sets of 0-based indices below `bound`, sorted and without repeats.
pub(crate) fn index_sets(
    sets: Option<&Bound<'_, PyDict>>,
    bound: usize,
    name: &str,
) -> PyResult<BTreeMap<String, Vec<usize>>> {
    let mut out = BTreeMap::new();
    let Some(sets) = sets else { return Ok(out) };
    for (k, v) in sets.iter() {
        let key: String = k
            .extract()
            .map_err(|_| PyValueError::new_err(format!("{name}: set names must be strings")))?;
        let members: Vec<i64> = v.extract().map_err(|_| {
            PyValueError::new_err(format!("{name}['{key}'] must be a sequence of integers"))
        })?;
        let mut idx = Vec::with_capacity(members.len());
        for x in members {
            match usize::try_from(x) {
                Ok(i) if i < bound => idx.push(i),
                _ => {
                    return Err(PyValueError::new_err(format!(
                        "{name}['{key}'] holds {x}, but there are {bound} (0-based indices)"
                    )));
                }
            }
        }
        idx.sort_unstable();
        idx.dedup();
        out.insert(key, idx);
    }
    Ok(out)
}

/// A skull given as a path or as `(vertices, triangles)`.
pub(crate) fn skull_of(
    py: Python<'_>,
    skull: &Bound<'_, PyAny>,
) -> PyResult<(TriSurface, PathBuf)> {
    if let Ok(t) = skull.cast::<PyTuple>()
        && t.len() == 2
    {
        let vertices = f64_rows(py, &t.get_item(0)?, 3, "skull vertices")?;
        let n = vertices.len();
        let tris = index_rows(py, &t.get_item(1)?, &[3], n, "skull triangles")?;
        let surface = TriSurface::new(
            vertices.into_iter().map(|v| Point3::new(v[0], v[1], v[2])).collect(),
            tris.into_iter().map(|t| [t[0], t[1], t[2]]).collect(),
        );
        return Ok((surface, PathBuf::from("<skull arrays>")));
    }
    let path: PathBuf = skull.extract().map_err(|_| {
        PyValueError::new_err("skull must be a path or a tuple (vertices (n, 3), triangles (m, 3))")
    })?;
    let s = py
        .detach(|| bs_mesh::io::read_surface(&path))
        .map_err(|e| raise(py, "Read", e.to_string(), false))?;
    Ok((s, path))
}

/// A volume's values (`per_voxel` per voxel, i fastest) as a numpy array (nx, ny, nz) or
/// (nx, ny, nz, per_voxel), without a copy: the array is in Fortran order (i fastest), so
/// `a.transpose()` is C-contiguous (nz, ny, nx), the (k, j, i) layout of OpenIGTLink and
/// of ITK.
pub(crate) fn volume_array<'py, T: numpy::Element + Copy>(
    py: Python<'py>,
    [nx, ny, nz]: [usize; 3],
    data: Vec<T>,
    per_voxel: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let err = |e: numpy::ndarray::ShapeError| PyValueError::new_err(e.to_string());
    if per_voxel == 1 {
        let a = numpy::ndarray::Array3::from_shape_vec((nz, ny, nx), data).map_err(err)?;
        Ok(a.permuted_axes([2, 1, 0]).into_pyarray(py).into_any())
    } else {
        let a =
            numpy::ndarray::Array4::from_shape_vec((nz, ny, nx, per_voxel), data).map_err(err)?;
        Ok(a.permuted_axes([2, 1, 0, 3]).into_pyarray(py).into_any())
    }
}

/// A 4×4 matrix as a numpy array.
pub(crate) fn affine<'py>(
    py: Python<'py>,
    m: &bs_mesh::nalgebra::Matrix4<f64>,
) -> Bound<'py, PyArray2<f64>> {
    let rows: Vec<f64> = (0..4).flat_map(|i| (0..4).map(move |j| m[(i, j)])).collect();
    Array2::from_shape_vec((4, 4), rows).expect("4 x 4").into_pyarray(py)
}
