//! `brainshift._native`: the Python bindings of brainshift (re-exported by the pure-Python
//! package `brainshift`, python/brainshift). Every entry point calls the same bs-scene
//! functions as the `brainshift` command, so a scene run from Python writes bit-identical
//! displacements; errors carry the command's messages.
//!
//! The GIL is released while files are read and scenes solved (`Python::detach`); a progress
//! callback re-attaches for each call.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use bs_contact::{Handler, MasterSurface, PaperParams};
use bs_mesh::{Element, Mesh, Point3, TriSurface};
use bs_scene::output::{RunContext, RunReport, report, write_outputs};
use bs_scene::scene::Algorithm;
use bs_scene::sweep::{self, RowOutcome, SlurmOptions, SweepError};
use bs_scene::{Prepared, Run, SceneError, Solved};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use crate::image::ImageArg;

mod igtl;
mod image;
mod session;

create_exception!(
    brainshift,
    BrainshiftError,
    PyException,
    "A scene, mesh, sweep or run that brainshift refuses, with the command line's message \
     (naming the file and key); `kind` is a short stable name of the error kind."
);

/// The Python exception of a library error: OSError for a file that could not be written,
/// BrainshiftError (with `kind`) for everything brainshift refuses.
fn raise(py: Python<'_>, kind: &str, message: String, write: bool) -> PyErr {
    if write {
        return PyOSError::new_err(message);
    }
    let err = BrainshiftError::new_err(message);
    let _ = err.value(py).setattr("kind", kind);
    err
}

/// The Python exception of an image that cannot be read (BrainshiftError, kind "Image").
fn image_error(py: Python<'_>, e: bs_image::ImageError) -> PyErr {
    scene_err(py, bs_scene::registration::image_error(e))
}

fn scene_err(py: Python<'_>, e: SceneError) -> PyErr {
    let write = matches!(e, SceneError::Write { .. });
    raise(py, e.kind(), e.to_string(), write)
}

fn sweep_err(py: Python<'_>, e: SweepError) -> PyErr {
    let write = matches!(e, SweepError::Write { .. });
    raise(py, e.kind(), e.to_string(), write)
}

/// Runs `f` on `threads` worker threads (the global pool, all cores, when `None`).
fn with_threads<T: Send>(
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
fn observer<'a>(
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
fn from_json(py: Python<'_>, text: &str) -> PyResult<Py<PyAny>> {
    Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
}

/// A 2-D float64 array with `cols` columns from anything numpy accepts.
fn f64_rows<'py>(
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
fn index_rows<'py>(
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
fn index_sets(
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
fn skull_of(py: Python<'_>, skull: &Bound<'_, PyAny>) -> PyResult<(TriSurface, PathBuf)> {
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

/// A brain-shift scene: a mesh with materials, boundary conditions and optionally a skull.
#[pyclass(module = "brainshift", frozen)]
struct Scene {
    prepared: Prepared,
}

#[pymethods]
impl Scene {
    /// A scene from arrays (see the package documentation for the keys of regions,
    /// boundaries and solver: the scene file's keys).
    #[new]
    #[pyo3(signature = (nodes, elements, *, regions, boundaries, node_sets=None,
                        element_sets=None, skull=None, contact_algorithm="paper",
                        units="mm", element=None, solver=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        nodes: &Bound<'_, PyAny>,
        elements: &Bound<'_, PyAny>,
        regions: &Bound<'_, PyAny>,
        boundaries: &Bound<'_, PyAny>,
        node_sets: Option<&Bound<'_, PyDict>>,
        element_sets: Option<&Bound<'_, PyDict>>,
        skull: Option<&Bound<'_, PyAny>>,
        contact_algorithm: &str,
        units: &str,
        element: Option<&str>,
        solver: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Scene> {
        let points = f64_rows(py, nodes, 3, "nodes")?;
        let n = points.len();
        let cells = index_rows(py, elements, &[4, 8], n, "elements")?;
        let mut mesh = Mesh::new(
            points.into_iter().map(|p| Point3::new(p[0], p[1], p[2])).collect(),
            cells.iter().map(|c| Element::from_nodes(c).expect("4 or 8 nodes")).collect(),
        );
        mesh.node_sets = index_sets(node_sets, n, "node_sets")?;
        mesh.element_sets = index_sets(element_sets, mesh.elements.len(), "element_sets")?;
        let skull = skull.map(|s| skull_of(py, s)).transpose()?;
        let scene = PyDict::new(py);
        scene.set_item("units", units)?;
        let mesh_table = PyDict::new(py);
        mesh_table.set_item("file", "<arrays>")?;
        if let Some(e) = element {
            mesh_table.set_item("element", e)?;
        }
        scene.set_item("mesh", mesh_table)?;
        scene.set_item("region", regions)?;
        scene.set_item("boundary", boundaries)?;
        if let Some((_, path)) = &skull {
            let c = PyDict::new(py);
            c.set_item("skull", path.to_string_lossy().as_ref())?;
            c.set_item("algorithm", contact_algorithm)?;
            scene.set_item("contact", c)?;
        }
        if let Some(s) = solver {
            scene.set_item("solver", s)?;
        }
        let json = py.import("json")?;
        let kwargs = PyDict::new(py);
        kwargs.set_item("default", py.import("builtins")?.getattr("float")?)?;
        let text: String = json.call_method("dumps", (scene,), Some(&kwargs))?.extract()?;
        let parsed: bs_scene::Scene = serde_json::from_str(&text)
            .map_err(|e| PyValueError::new_err(format!("scene from arrays: {e}")))?;
        parsed.validate().map_err(|m| PyValueError::new_err(format!("scene from arrays: {m}")))?;
        let prepared = py
            .detach(|| {
                Prepared::from_parts(Path::new("<arrays>"), parsed, mesh, skull.map(|s| s.0))
            })
            .map_err(|e| scene_err(py, e))?;
        Ok(Scene { prepared })
    }

    /// Reads a scene file (TOML) and everything it names, as `brainshift check` does first.
    #[staticmethod]
    fn from_toml(py: Python<'_>, path: PathBuf) -> PyResult<Scene> {
        let prepared = py.detach(|| Prepared::load(&path)).map_err(|e| scene_err(py, e))?;
        Ok(Scene { prepared })
    }

    /// The scene file (`<arrays>` for a scene built from arrays).
    #[getter]
    fn path(&self) -> PathBuf {
        self.prepared.path.clone()
    }

    /// Things worth knowing that do not stop a run.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.prepared.warnings.clone()
    }

    /// Number of mesh nodes.
    #[getter]
    fn num_nodes(&self) -> usize {
        self.prepared.mesh.nodes.len()
    }

    /// Number of mesh elements.
    #[getter]
    fn num_elements(&self) -> usize {
        self.prepared.mesh.elements.len()
    }

    /// The frame of the scene's mesh: "RAS" or "LPS".
    #[getter]
    fn space(&self) -> &'static str {
        self.prepared.scene.space.space().name()
    }

    /// The length unit of the scene's mesh ("mm", "m", ...).
    #[getter]
    fn units(&self) -> &'static str {
        self.prepared.scene.units.symbol()
    }

    /// Everything a run does before solving (memory, composition, initial gap), as the
    /// dict of what `brainshift check` prints (the keys of `brainshift check --json`);
    /// raises BrainshiftError if the scene cannot run.
    fn check(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let prepared = self.prepared.clone();
        let c = py
            .detach(|| bs_scene::check::check_prepared(prepared))
            .map_err(|e| scene_err(py, e))?;
        from_json(py, &serde_json::to_string(&c.report()).expect("a check report serialises"))
    }

    /// Solves and verifies the scene (as `brainshift run`), with the GIL released.
    /// `threads`: worker threads (None: all cores). `progress`: called with a dict per
    /// solver step or iteration (step, load_factor, error_estimate, max_displacement,
    /// nodes_in_contact); an exception it raises is raised when the solve ends.
    #[pyo3(signature = (threads=None, progress=None))]
    fn run(
        &self,
        py: Python<'_>,
        threads: Option<usize>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<RunResult> {
        let started = Instant::now();
        let prepared = self.prepared.clone();
        let mut callback_error: Option<PyErr> = None;
        let outcome = py.detach(|| {
            with_threads(threads, || {
                let threads = rayon::current_num_threads();
                let mut run = Run::prepare(prepared)?;
                let solved = run.solve(&mut observer(progress.as_ref(), &mut callback_error))?;
                Ok::<_, SceneError>((run, solved, threads))
            })
        });
        let (run, solved, threads) =
            outcome.map_err(PyValueError::new_err)?.map_err(|e| scene_err(py, e))?;
        if let Some(e) = callback_error {
            return Err(e);
        }
        let ctx = RunContext { total_seconds: started.elapsed().as_secs_f64(), threads };
        Ok(RunResult::new(&run, solved, ctx))
    }

    fn __repr__(&self) -> String {
        format!(
            "<brainshift.Scene {}: {} nodes, {} elements>",
            self.prepared.path.display(),
            self.prepared.mesh.nodes.len(),
            self.prepared.mesh.elements.len()
        )
    }
}

/// A verified run: displacements, node ids, the report, and `write(dir)`.
#[pyclass(module = "brainshift", name = "Result", frozen)]
struct RunResult {
    inner: Mutex<(Prepared, Solved)>,
    report: RunReport,
    report_json: String,
    displacements: Vec<f64>,
    node_ids: Vec<u64>,
}

impl RunResult {
    fn new(run: &Run, solved: Solved, ctx: RunContext) -> RunResult {
        let r = report(run, &solved, ctx);
        let report_json = serde_json::to_string(&r).expect("a report serialises");
        let displacements =
            solved.solution.displacements.iter().flat_map(|d| [d.x, d.y, d.z]).collect();
        let node_ids = run.prepared.mesh.node_ids.clone();
        RunResult {
            inner: Mutex::new((run.prepared.clone(), solved)),
            report: r,
            report_json,
            displacements,
            node_ids,
        }
    }
}

impl RunResult {
    /// This result as the registration outputs read it (mesh, displacements, frame, unit,
    /// skull).
    fn registration(&self, py: Python<'_>) -> PyResult<bs_scene::registration::RunResult> {
        let guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let (p, solved) = &*guard;
        bs_scene::registration::RunResult::new(
            &p.path,
            p.mesh.clone(),
            solved.solution.displacements.clone(),
            p.scene.space.space(),
            p.scene.units,
        )
        .map(|r| {
            let mut r = r.with_skull(p.skull.clone());
            r.resected = p.resection.is_some();
            r
        })
        .map_err(|e| scene_err(py, e))
    }
}

/// A volume's values (`per_voxel` per voxel, i fastest) as a numpy array (nx, ny, nz) or
/// (nx, ny, nz, per_voxel), without a copy: the array is in Fortran order (i fastest), so
/// `a.transpose()` is C-contiguous (nz, ny, nx), the (k, j, i) layout of OpenIGTLink and
/// of ITK.
fn volume_array<'py, T: numpy::Element + Copy>(
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

/// A surface as numpy arrays: points (k, 3), triangles (t, 3), the node of each point (k).
type Surface<'py> =
    (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>, Bound<'py, PyArray1<i64>>);

/// A 4×4 matrix as a numpy array.
fn affine<'py>(py: Python<'py>, m: &bs_mesh::nalgebra::Matrix4<f64>) -> Bound<'py, PyArray2<f64>> {
    let rows: Vec<f64> = (0..4).flat_map(|i| (0..4).map(move |j| m[(i, j)])).collect();
    Array2::from_shape_vec((4, 4), rows).expect("4 x 4").into_pyarray(py)
}

#[pymethods]
impl RunResult {
    /// Nodal displacements, float64 (n, 3), in the order of `node_ids`.
    #[getter]
    fn displacements<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let n = self.node_ids.len();
        let a = Array2::from_shape_vec((n, 3), self.displacements.clone())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(a.into_pyarray(py))
    }

    /// The mesh file's node ids (uint64, n).
    #[getter]
    fn node_ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.node_ids.clone())
    }

    /// The run's report: a dict with the keys of report.json.
    #[getter]
    fn report(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        from_json(py, &self.report_json)
    }

    /// Writes result.vtu, displacements.csv and report.json into `dir` (created if
    /// missing), as `brainshift run --out dir`; returns their paths.
    fn write<'py>(&self, py: Python<'py>, dir: PathBuf) -> PyResult<Bound<'py, PyDict>> {
        let written = py
            .detach(|| {
                let guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
                let (prepared, solved) = &*guard;
                write_outputs(&dir, prepared, solved, &self.report)
            })
            .map_err(|e| scene_err(py, e))?;
        let d = PyDict::new(py);
        d.set_item("vtu", written.vtu)?;
        d.set_item("vtk", written.vtk)?;
        d.set_item("skull", written.skull)?;
        d.set_item("csv", written.csv)?;
        d.set_item("report", written.report)?;
        Ok(d)
    }

    /// The pre-operative image `image` (a path to .nii, .nii.gz, .nrrd, .nhdr, or a
    /// `brainshift.Image` already read) warped into this result's configuration, as
    /// `brainshift warp` computes it: `(array, affine)`, the array (nx, ny, nz) on the
    /// image's grid (float32; uint32 labels with `labels=True`, nearest voxel, from a path
    /// only; a resection's cavity takes `cavity_label`, default 0), `affine` the 4×4
    /// voxel-index-to-RAS (mm) matrix.
    #[pyo3(signature = (image, labels=false, cavity_label=0))]
    fn warp<'py>(
        &self,
        py: Python<'py>,
        image: &Bound<'py, PyAny>,
        labels: bool,
        cavity_label: u32,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyArray2<f64>>)> {
        let result = self.registration(py)?;
        let image = ImageArg::of(image)?;
        let v = match (&image, labels) {
            (ImageArg::File(p), true) => {
                let v = py
                    .detach(|| bs_scene::registration::warp_labels_volume(&result, p, cavity_label))
                    .map_err(|e| scene_err(py, e))?;
                let a = affine(py, v.grid.voxel_to_world());
                return Ok((volume_array(py, v.grid.dims(), v.data, 1)?, a));
            }
            (ImageArg::Loaded(_), true) => {
                return Err(PyValueError::new_err(
                    "labels=True reads the labelmap itself: pass its path, not an Image",
                ));
            }
            (ImageArg::Loaded(i), false) => {
                py.detach(|| i.warp(&result)).map_err(|e| scene_err(py, e))?
            }
            (ImageArg::File(p), false) => py
                .detach(|| bs_scene::registration::warp_volume(&result, p))
                .map_err(|e| scene_err(py, e))?,
        };
        Ok((volume_array(py, v.grid.dims(), v.data, 1)?, affine(py, v.grid.voxel_to_world())))
    }

    /// The displacement field d(y) = X(y) − y on the grid of `reference` (a path or a
    /// `brainshift.Image`), as `brainshift field` computes it: `(array, affine)`, the array
    /// float32 (nx, ny, nz, 3) of RAS vectors in mm (zero beyond the skull), `affine`
    /// voxel index to RAS (mm).
    fn field<'py>(
        &self,
        py: Python<'py>,
        reference: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyArray2<f64>>)> {
        let result = self.registration(py)?;
        let reference = ImageArg::of(reference)?;
        let v = match &reference {
            ImageArg::Loaded(i) => py.detach(|| i.field(&result)),
            ImageArg::File(p) => {
                let grid = reference.grid(py)?;
                py.detach(|| bs_scene::registration::field_on(&result, &grid, p))
            }
        }
        .map_err(|e| scene_err(py, e))?;
        let data: Vec<f32> = v.data.iter().flatten().copied().collect();
        Ok((volume_array(py, v.grid.dims(), data, 3)?, affine(py, v.grid.voxel_to_world())))
    }

    /// The inverse map of this result on the grid of `image` (a path or a
    /// `brainshift.Image`), built once: `warp(...)` and `field()` from it cost a resample
    /// each, what a live session does after every update.
    fn inverse_map(&self, py: Python<'_>, image: &Bound<'_, PyAny>) -> PyResult<image::InverseMap> {
        let result = self.registration(py)?;
        let image = ImageArg::of(image)?;
        let grid = image.grid(py)?;
        let path = image.path().to_path_buf();
        let map = py
            .detach(|| {
                bs_scene::registration::InverseMap::new(&result, &grid, bs_image::Space::Ras, &path)
            })
            .map_err(|e| scene_err(py, e))?;
        Ok(image::InverseMap { map, grid, gap: std::sync::OnceLock::new() })
    }

    /// The deformed boundary surface of the brain (every element's free faces, oriented
    /// outwards) at X + u, in the scene's frame and unit: `(points (k, 3) float64,
    /// triangles (t, 3) int64, node_index (k,) int64)`, node_index the 0-based node of each
    /// point (rows of `displacements`).
    fn surface<'py>(&self, py: Python<'py>) -> PyResult<Surface<'py>> {
        let b = py.detach(|| {
            let guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
            let (p, solved) = &*guard;
            bs_scene::output::deformed_boundary(&p.mesh, &solved.solution.displacements)
        });
        let k = b.surface.vertices.len();
        let t = b.surface.triangles.len();
        let err = |e: numpy::ndarray::ShapeError| PyValueError::new_err(e.to_string());
        let pts: Vec<f64> = b.surface.vertices.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        let tris: Vec<i64> = b.surface.triangles.iter().flat_map(|t| t.map(|v| v as i64)).collect();
        let nodes: Vec<i64> = b.volume_node.iter().map(|&n| n as i64).collect();
        Ok((
            Array2::from_shape_vec((k, 3), pts).map_err(err)?.into_pyarray(py),
            Array2::from_shape_vec((t, 3), tris).map_err(err)?.into_pyarray(py),
            PyArray1::from_vec(py, nodes),
        ))
    }

    fn __repr__(&self) -> String {
        format!("<brainshift.Result: {} nodes>", self.node_ids.len())
    }
}

/// Reads a volume mesh: a dict with nodes (float64 n×3), node_ids, elements (int64 m×4 for
/// tets, m×8 for hexes; a mixed mesh pads tets with -1), element_ids, and node_sets /
/// element_sets (dicts of 0-based index arrays).
#[pyfunction]
fn read_mesh<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
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
fn gap<'py>(
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
            let mut handler = Handler::from_master(
                bs_scene::compose::algorithm(algorithm),
                master.clone(),
                PaperParams::default(),
            )
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

/// `brainshift sweep plan SWEEP --out DIR`: returns the manifest (a dict).
#[pyfunction]
fn sweep_plan(py: Python<'_>, sweep_file: PathBuf, out: PathBuf) -> PyResult<Py<PyAny>> {
    let m = py.detach(|| sweep::plan(&sweep_file, &out)).map_err(|e| sweep_err(py, e))?;
    from_json(py, &serde_json::to_string(&m).expect("a manifest serialises"))
}

/// `brainshift sweep run DIR --index I`: returns "ran" or "skipped"; a failed row raises
/// BrainshiftError (its error.json written).
#[pyfunction]
#[pyo3(signature = (dir, index, threads=None))]
fn sweep_run(
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
fn sweep_collect<'py>(
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
fn sweep_emit_slurm(
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

/// The native module `brainshift._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("BrainshiftError", m.py().get_type::<BrainshiftError>())?;
    m.add_class::<Scene>()?;
    m.add_class::<RunResult>()?;
    m.add_class::<session::Session>()?;
    m.add_class::<image::Image>()?;
    m.add_class::<image::InverseMap>()?;
    m.add_function(wrap_pyfunction!(image::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(igtl::crc64, m)?)?;
    m.add_function(wrap_pyfunction!(read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(gap, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_plan, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_run, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_collect, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_emit_slurm, m)?)?;
    Ok(())
}
