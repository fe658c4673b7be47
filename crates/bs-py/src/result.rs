//! `Result`: a run's displacements, report, outputs, warped images and fields.

use std::path::PathBuf;
use std::sync::Mutex;

use bs_scene::output::{RunContext, RunReport, report, write_outputs};
use bs_scene::{Prepared, Run, Solved};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{affine, from_json, scene_err, volume_array};
use crate::image;
use crate::image::ImageArg;

/// A surface as numpy arrays: points (k, 3), triangles (t, 3), the node of each point (k).
type Surface<'py> =
    (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>, Bound<'py, PyArray1<i64>>);

/// A verified run: displacements, node ids, the report, and `write(dir)`.
#[pyclass(module = "brainshift", name = "Result", frozen)]
pub(crate) struct VerifiedRun {
    inner: Mutex<(Prepared, Solved)>,
    report: RunReport,
    report_json: String,
    displacements: Vec<f64>,
    node_ids: Vec<u64>,
}

impl VerifiedRun {
    pub(crate) fn new(run: &Run, solved: Solved, ctx: RunContext) -> VerifiedRun {
        let r = report(run, &solved, ctx);
        let report_json = serde_json::to_string(&r).expect("a report serialises");
        let displacements =
            solved.solution.displacements.iter().flat_map(|d| [d.x, d.y, d.z]).collect();
        let node_ids = run.prepared.mesh.node_ids.clone();
        VerifiedRun {
            inner: Mutex::new((run.prepared.clone(), solved)),
            report: r,
            report_json,
            displacements,
            node_ids,
        }
    }
}

impl VerifiedRun {
    /// This result as the registration outputs read it (mesh, displacements, frame, unit,
    /// skull).
    fn registration(&self, py: Python<'_>) -> PyResult<bs_register::registration::RunResult> {
        let guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let (p, solved) = &*guard;
        bs_register::registration::RunResult::new(
            &p.path,
            p.mesh.clone(),
            solved.solution.displacements.clone(),
            p.scene.space,
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

#[pymethods]
impl VerifiedRun {
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
                    .detach(|| {
                        bs_register::registration::warp_labels_volume(&result, p, cavity_label)
                    })
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
                .detach(|| bs_register::registration::warp_volume(&result, p))
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
                py.detach(|| bs_register::registration::field_on(&result, &grid, p))
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
            .detach(|| bs_register::registration::InverseMap::new(&result, &grid, &path))
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

    /// σ of the fitted displacement, as `brainshift run --uncertainty samples` samples it
    /// (docs/uncertainty.md): a dict with `sigma` (n, 3) float64 (σ along x, y, z per node,
    /// rows of `displacements`, the scene's unit), `total` (n,) and the keys of report.json's
    /// `uncertainty` (samples, iterations, seconds, parts, max_sigma, max_node, max_at,
    /// mean_sigma, landmarks, held_out: the scene's held-out landmarks' check and the
    /// factor σ was scaled by, or None). Raises BrainshiftError for a scene with nothing fitted,
    /// ValueError for fewer than 2 samples.
    #[pyo3(signature = (samples=32, seed=1))]
    fn uncertainty<'py>(
        &self,
        py: Python<'py>,
        samples: i64,
        seed: u64,
    ) -> PyResult<Bound<'py, PyDict>> {
        if samples < 2 {
            return Err(PyValueError::new_err(format!(
                "uncertainty(samples={samples}): give at least 2 samples (32 give σ to about 13 %)"
            )));
        }
        let params = bs_scene::uncertainty::UncertaintyParams {
            samples: samples as usize,
            seed,
            ..Default::default()
        };
        let (u, report) = py
            .detach(|| {
                let guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
                let (prepared, solved) = &*guard;
                // The solver's preparation again (what `run` kept): the tangent at the answer
                // needs it; the answer itself is this result's.
                let mut run = Run::prepare(prepared.clone())?;
                let u = bs_scene::uncertainty::sample(&mut run, solved, &params)?;
                let report = bs_scene::uncertainty::UncertaintyReport::of(&run, &u);
                Ok::<_, bs_scene::SceneError>((u, report))
            })
            .map_err(|e| scene_err(py, e))?;
        let n = u.sigma.len();
        let flat: Vec<f64> = u.sigma.iter().flatten().copied().collect();
        let sigma = Array2::from_shape_vec((n, 3), flat)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let total: Vec<f64> = (0..n).map(|a| u.total(a)).collect();
        let json = serde_json::to_string(&report).expect("a report serialises");
        let d: Bound<'py, PyDict> = from_json(py, &json)?.into_bound(py).cast_into()?;
        d.set_item("sigma", sigma.into_pyarray(py))?;
        d.set_item("total", PyArray1::from_vec(py, total))?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!("<brainshift.Result: {} nodes>", self.node_ids.len())
    }
}
