//! Parameter sweeps: plan, run, collect, emit Slurm scripts.

use std::path::PathBuf;

use bs_mesh::Point3;
use bs_sweep::{self as sweep, RowOutcome, SlurmOptions};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{from_json, sweep_err, with_threads};

/// `brainshift sweep plan SWEEP --out DIR`: returns the manifest (a dict).
#[pyfunction]
pub(crate) fn sweep_plan(py: Python<'_>, sweep_file: PathBuf, out: PathBuf) -> PyResult<Py<PyAny>> {
    let m = py.detach(|| sweep::plan(&sweep_file, &out)).map_err(|e| sweep_err(py, e))?;
    from_json(py, &serde_json::to_string(&m).expect("a manifest serialises"))
}

/// `brainshift sweep run DIR --index I`: returns "ran" or "skipped"; a failed row raises
/// BrainshiftError (its error.json written).
#[pyfunction]
#[pyo3(signature = (dir, index, threads=None))]
pub(crate) fn sweep_run(
    py: Python<'_>,
    dir: PathBuf,
    index: usize,
    threads: Option<usize>,
) -> PyResult<&'static str> {
    let outcome = py
        .detach(|| {
            with_threads(threads, || {
                sweep::run_row(&dir, index, rayon::current_num_threads(), &mut |_| {})
            })
        })
        .map_err(PyValueError::new_err)?
        .map_err(|e| sweep_err(py, e))?;
    Ok(match outcome {
        RowOutcome::Ran(_) => "ran",
        RowOutcome::Skipped(_) => "skipped",
    })
}

/// `brainshift sweep collect DIR [--points P]`: writes DIR/summary.csv and returns its rows
/// as dicts (the CSV's columns; empty fields are None). `points`: a points CSV
/// (name,x,y,z) or a dict name -> (x, y, z).
#[pyfunction]
#[pyo3(signature = (dir, points=None))]
pub(crate) fn sweep_collect<'py>(
    py: Python<'py>,
    dir: PathBuf,
    points: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyList>> {
    let named = match points {
        None => Vec::new(),
        Some(p) => match p.cast::<PyDict>() {
            Ok(d) => {
                let mut v = Vec::new();
                for (k, xyz) in d.iter() {
                    let name: String = k.extract()?;
                    let c: (f64, f64, f64) = xyz.extract().map_err(|_| {
                        PyValueError::new_err(format!("points['{name}'] must be (x, y, z)"))
                    })?;
                    v.push(sweep::NamedPoint { name, point: Point3::new(c.0, c.1, c.2) });
                }
                v
            }
            Err(_) => {
                let path: PathBuf = p.extract().map_err(|_| {
                    PyValueError::new_err("points must be a CSV path or a dict name -> (x, y, z)")
                })?;
                sweep::read_points(&path).map_err(|e| sweep_err(py, e))?
            }
        },
    };
    let s = py.detach(|| sweep::collect(&dir, &named)).map_err(|e| sweep_err(py, e))?;
    let rows = PyList::empty(py);
    for r in &s.rows {
        let d = PyDict::new(py);
        d.set_item("index", r.index)?;
        for (k, v) in s.keys.iter().zip(&r.parameters) {
            match v {
                sweep::AxisValue::Number(x) => d.set_item(k, *x)?,
                sweep::AxisValue::Text(t) => d.set_item(k, t)?,
            }
        }
        d.set_item("status", r.status.name())?;
        d.set_item("error", r.error.clone())?;
        d.set_item("max_displacement", r.max_displacement)?;
        for (p, u) in s.points.iter().zip(&r.at_points) {
            let c = u.map(|u| [u.x, u.y, u.z, u.norm()]);
            for (i, name) in ["ux", "uy", "uz", "umag"].iter().enumerate() {
                d.set_item(format!("{}_{name}", p.name), c.map(|c| c[i]))?;
            }
        }
        d.set_item("nodes_in_contact", r.nodes_in_contact)?;
        d.set_item("solve_seconds", r.solve_seconds)?;
        d.set_item("units", r.units.clone())?;
        rows.append(d)?;
    }
    Ok(rows)
}

/// `brainshift sweep emit-slurm DIR`: writes DIR/sweep.slurm, returns its path.
#[pyfunction]
#[pyo3(signature = (dir, max_parallel=None, time="01:00:00", cpus_per_task=2, program="brainshift"))]
pub(crate) fn sweep_emit_slurm(
    py: Python<'_>,
    dir: PathBuf,
    max_parallel: Option<usize>,
    time: &str,
    cpus_per_task: usize,
    program: &str,
) -> PyResult<PathBuf> {
    let opts = SlurmOptions {
        max_parallel,
        time: time.to_string(),
        cpus_per_task,
        program: program.to_string(),
    };
    let s = py.detach(|| sweep::emit_slurm(&dir, &opts)).map_err(|e| sweep_err(py, e))?;
    Ok(s.path)
}
