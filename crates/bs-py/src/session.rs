//! `brainshift.Session`: a live session of a scene (bs-scene's `Session`): the
//! pre-operative work done once, then `update(...)` solves each new measurement warm from
//! the last converged state and returns the same `Result` as `Scene.run`; `reset()` goes
//! back to the reference state. The GIL is released while solving.

use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

use bs_mesh::{Point3, TriSurface, Vector3};
use bs_scene::output::RunContext;
use bs_scene::scene::LandmarkFiles;
use bs_scene::{BoundaryValues, SceneError, Update};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::convert::{f64_rows, index_rows, observer, scene_err, with_threads};
use crate::result::VerifiedRun;
use crate::scene::Scene;

/// A live session of a scene: `update` takes new measurements of the scene's prescribed
/// boundaries (keyed by node set) and solves from the last good state.
#[pyclass(module = "brainshift", frozen)]
pub(crate) struct Session {
    pub(crate) inner: Mutex<bs_scene::Session>,
    threads: Option<usize>,
}

/// `v` as a pair of arrays, or a file path.
enum Given<'a, 'py> {
    Arrays(&'a Bound<'py, PyTuple>),
    File(PathBuf),
}

fn given<'a, 'py>(v: &'a Bound<'py, PyAny>, what: &str) -> PyResult<Given<'a, 'py>> {
    match v.cast::<PyTuple>() {
        Ok(t) if t.len() == 2 => Ok(Given::Arrays(t)),
        _ => v.extract::<PathBuf>().map(Given::File).map_err(|_| {
            PyValueError::new_err(format!("{what} must be a file path or a pair of arrays"))
        }),
    }
}

fn points(py: Python<'_>, v: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Point3<f64>>> {
    Ok(f64_rows(py, v, 3, what)?.into_iter().map(Point3::from).collect())
}

impl Session {
    /// The updates of one `update` call.
    #[allow(clippy::too_many_arguments)]
    fn asked(
        &self,
        py: Python<'_>,
        displacements: Option<&Bound<'_, PyDict>>,
        surface: Option<&Bound<'_, PyDict>>,
        landmarks: Option<&Bound<'_, PyDict>>,
        scans: Option<&Bound<'_, PyDict>>,
        gravity: Option<[f64; 3]>,
    ) -> PyResult<Vec<Update>> {
        let mut updates = Vec::new();
        let key = |k: Bound<'_, PyAny>, what: &str| -> PyResult<String> {
            k.extract()
                .map_err(|_| PyValueError::new_err(format!("{what}: keys are node set names")))
        };
        for (k, v) in displacements.into_iter().flat_map(|d| d.iter()) {
            let set = key(k, "displacements")?;
            let values = match v.extract::<[f64; 3]>() {
                Ok(d) => BoundaryValues::Uniform(Vector3::from(d)),
                Err(_) => {
                    let rows = f64_rows(py, &v, 3, &format!("displacements['{set}']"))?;
                    BoundaryValues::PerNode(rows.into_iter().map(Vector3::from).collect())
                }
            };
            updates.push(Update::Boundary { set, values });
        }
        for (k, v) in surface.into_iter().flat_map(|d| d.iter()) {
            let set = key(k, "surface")?;
            let what = format!("surface['{set}']");
            let s = match given(&v, &what)? {
                Given::Arrays(t) => {
                    let vertices = points(py, &t.get_item(0)?, &format!("{what} points"))?;
                    let n = vertices.len();
                    let tris =
                        index_rows(py, &t.get_item(1)?, &[3], n, &format!("{what} triangles"))?;
                    TriSurface::new(
                        vertices,
                        tris.into_iter().map(|t| [t[0], t[1], t[2]]).collect(),
                    )
                }
                Given::File(path) => bs_mesh::io::read_surface(&path)
                    .map_err(|e| PyValueError::new_err(format!("{what}: {e}")))?,
            };
            updates.push(Update::Boundary { set, values: BoundaryValues::Surface(s) });
        }
        let s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        for (k, v) in landmarks.into_iter().flat_map(|d| d.iter()) {
            let set = key(k, "landmarks")?;
            let what = format!("landmarks['{set}']");
            let (pre, intra) = match given(&v, &what)? {
                Given::Arrays(t) => (
                    points(py, &t.get_item(0)?, &format!("{what} pre"))?,
                    points(py, &t.get_item(1)?, &format!("{what} intra"))?,
                ),
                Given::File(path) => {
                    let space = s.run().prepared.scene.space;
                    let pairs =
                        bs_scene::measure::pairs::read_pairs(&LandmarkFiles::Pairs(path), space)
                            .map_err(|e| PyValueError::new_err(format!("{what}: {e}")))?;
                    (pairs.pre, pairs.intra)
                }
            };
            if pre.len() != intra.len() {
                return Err(PyValueError::new_err(format!(
                    "{what}: {} pre-operative and {} intra-operative points; give pairs",
                    pre.len(),
                    intra.len()
                )));
            }
            updates.push(Update::Landmarks { set, pre, intra });
        }
        for (k, v) in scans.into_iter().flat_map(|d| d.iter()) {
            let set = key(k, "points")?;
            let p = points(py, &v, &format!("points['{set}']"))?;
            updates.push(Update::Scan { set, points: p });
        }
        let kinds = [
            updates.iter().any(|u| matches!(u, Update::Boundary { .. })),
            updates.iter().any(|u| matches!(u, Update::Landmarks { .. })),
            updates.iter().any(|u| matches!(u, Update::Scan { .. })),
        ];
        if kinds.iter().filter(|&&k| k).count() > 1 {
            return Err(PyValueError::new_err(
                "update: give new scans (points=), new landmarks (landmarks=) or new boundary \
                 values (displacements=, surface=) in one call, not two of them; call update \
                 twice",
            ));
        }
        if let Some(g) = gravity {
            updates.push(Update::Gravity(g));
        }
        Ok(updates)
    }
}

#[pymethods]
impl Session {
    /// Prepares `scene` once (composition, contact lists, the solver's preconditioner).
    /// `threads`: worker threads of every update (None: all cores).
    #[new]
    #[pyo3(signature = (scene, threads=None))]
    fn new(py: Python<'_>, scene: &Scene, threads: Option<usize>) -> PyResult<Session> {
        let prepared = scene.prepared.clone();
        let s = py
            .detach(|| with_threads(threads, || bs_scene::Session::new(prepared)))
            .map_err(PyValueError::new_err)?
            .map_err(|e| scene_err(py, e))?;
        Ok(Session { inner: Mutex::new(s), threads })
    }

    /// Solves new measurements warm from the last good state and verifies the result.
    /// `displacements={"SET": [dx, dy, dz]}` (uniform) or an (n, 3) array in the order of
    /// `set_nodes("SET")`; `surface={"SET": path or (points, triangles)}`;
    /// new values of prescribed boundaries (boundaries not named keep their last values).
    /// `landmarks={"SET": csv path or (pre, intra)}`: landmark pairs, fitted from the
    /// reference state with the session's preparation — on the node set of a landmark
    /// `[[measurement]]` (`landmark_sets()`) its new pairs; on a prescribed boundary's that
    /// holds x, y and z, through that boundary as a cold run of the scene with the boundary
    /// replaced by a landmark `[[measurement]]` (sigma 1 mm) fits them, until the next
    /// boundary values. `points={"SET": (m, 3) array}`: a new
    /// scan of the `[[measurement]]` on that node set, fitted from the reference state with
    /// the session's preparation (scene frame and units, before the scene's rigid
    /// correction; `measured_sets()` lists the keys); not in the same call as boundary
    /// values. `gravity=[x, y, z]`: the scene's `[gravity]` turned to this direction (scene
    /// frame; the head repositioned), alone or with any of the above. On an error the
    /// session stays at its last good state (and direction).
    /// `progress`: called with a dict per solver iteration, as in `Scene.run`.
    #[pyo3(signature = (displacements=None, surface=None, landmarks=None, points=None, gravity=None, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn update(
        &self,
        py: Python<'_>,
        displacements: Option<&Bound<'_, PyDict>>,
        surface: Option<&Bound<'_, PyDict>>,
        landmarks: Option<&Bound<'_, PyDict>>,
        points: Option<&Bound<'_, PyDict>>,
        gravity: Option<[f64; 3]>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<VerifiedRun> {
        let updates = self.asked(py, displacements, surface, landmarks, points, gravity)?;
        self.solve_with(py, progress.as_ref(), |s, observe| s.apply(&updates, observe))
    }

    /// Resects the region whose element set is `region` (its elements leave the model; the
    /// cavity's walls become free) and solves warm from the last good state; `regions()`
    /// lists the keys. On an error the session keeps its model and state.
    #[pyo3(signature = (region, progress=None))]
    fn resect(
        &self,
        py: Python<'_>,
        region: &str,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<VerifiedRun> {
        self.solve_with(py, progress.as_ref(), |s, observe| s.resect(region, observe))
    }

    /// The element sets of the regions still in the model: the keys of `resect`.
    fn regions(&self) -> Vec<String> {
        let s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        s.regions().into_iter().map(str::to_string).collect()
    }

    /// Back to the reference state and the scene's own boundary values (a turned gravity
    /// and resected regions stay).
    fn reset(&self) {
        self.inner.lock().unwrap_or_else(|e| e.into_inner()).reset();
    }

    /// The node ids of node set `name` of a prescribed boundary, in the order an (n, 3)
    /// `displacements` array follows.
    fn set_nodes(&self, py: Python<'_>, name: &str) -> PyResult<Vec<u64>> {
        let s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let nodes = s.set_nodes(name).map_err(|e| scene_err(py, e))?;
        let ids = &s.run().prepared.mesh.node_ids;
        Ok(nodes.into_iter().map(|n| ids[n]).collect())
    }

    /// The direction of the scene's gravity now (`None` without `[gravity]`).
    fn gravity(&self) -> Option<[f64; 3]> {
        let s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        s.gravity_direction()
    }

    /// The node sets of the scene's scanned-surface measurements: the keys of `update`'s
    /// `points`.
    fn measured_sets(&self) -> Vec<String> {
        let s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        s.measured_sets().into_iter().map(str::to_string).collect()
    }

    /// The node sets of the scene's landmark measurements: the keys of `update`'s
    /// `landmarks` that are fitted (other keys name boundaries whose landmarks are imposed).
    fn landmark_sets(&self) -> Vec<String> {
        let s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        s.landmark_sets().into_iter().map(str::to_string).collect()
    }

    /// The node sets of the scene's boundaries that prescribe displacements: the keys
    /// `update` takes.
    fn prescribed_sets(&self) -> Vec<String> {
        let s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        s.prescribed_sets().into_iter().map(str::to_string).collect()
    }

    fn __repr__(&self) -> String {
        let s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        format!(
            "<brainshift.Session {}: {} nodes>",
            s.run().prepared.path.display(),
            s.displacements().len()
        )
    }
}

impl Session {
    /// Runs `call` on the locked session without the GIL, on the session's threads, with
    /// `progress` (if any) called per solver iteration; its verified result as a `Result`.
    /// An exception raised by `progress` is raised after the solve.
    fn solve_with(
        &self,
        py: Python<'_>,
        progress: Option<&Py<PyAny>>,
        call: impl FnOnce(
            &mut bs_scene::Session,
            &mut dyn FnMut(&bs_scene::Progress),
        ) -> Result<bs_scene::Solved, SceneError>
        + Send,
    ) -> PyResult<VerifiedRun> {
        let started = Instant::now();
        let mut callback_error: Option<PyErr> = None;
        let outcome = py.detach(|| {
            with_threads(self.threads, || {
                let threads = rayon::current_num_threads();
                let mut s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
                let mut observe = observer(progress, &mut callback_error);
                let solved = call(&mut s, &mut observe)?;
                let ctx = RunContext { total_seconds: started.elapsed().as_secs_f64(), threads };
                Ok::<_, SceneError>(VerifiedRun::new(s.run(), solved, ctx))
            })
        });
        let result = outcome.map_err(PyValueError::new_err)?.map_err(|e| scene_err(py, e))?;
        match callback_error {
            Some(e) => Err(e),
            None => Ok(result),
        }
    }
}
