//! `brainshift.Session`: a live session of a scene (bs-scene's `Session`): the
//! pre-operative work done once, then `update(...)` solves each new measurement warm from
//! the last converged state and returns the same `Result` as `Scene.run`; `reset()` goes
//! back to the reference state. The GIL is released while solving.

use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use bs_mesh::{Point3, TriSurface, Vector3};
use bs_scene::output::RunContext;
use bs_scene::{BoundaryLoad, SceneError};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::convert::{f64_rows, index_rows, observer, scene_err, with_threads};
use crate::result::RunResult;
use crate::scene::Scene;

/// A live session of a scene: `update` takes new measurements of the scene's prescribed
/// boundaries (keyed by node set) and solves from the last good state.
#[pyclass(module = "brainshift", frozen)]
pub(crate) struct Session {
    inner: Mutex<bs_scene::Session>,
    threads: Option<usize>,
    /// Temporary files of array-given surfaces and landmarks.
    scratch: PathBuf,
}

/// A unique scratch folder per session.
fn scratch_dir() -> PathBuf {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let k = NEXT.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!("brainshift-session-{}-{k}", std::process::id()))
}

/// `v` as a file path, or a pair of arrays that `write` puts in a scratch file.
fn path_or_arrays(
    v: &Bound<'_, PyAny>,
    what: &str,
    write: impl FnOnce(&Bound<'_, PyTuple>) -> PyResult<PathBuf>,
) -> PyResult<PathBuf> {
    match v.cast::<PyTuple>() {
        Ok(t) if t.len() == 2 => write(t),
        _ => v.extract::<PathBuf>().map_err(|_| {
            PyValueError::new_err(format!("{what} must be a file path or a pair of arrays"))
        }),
    }
}

impl Session {
    /// The boundary loads of one `update` call.
    fn loads(
        &self,
        py: Python<'_>,
        displacements: Option<&Bound<'_, PyDict>>,
        surface: Option<&Bound<'_, PyDict>>,
        landmarks: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Vec<(String, BoundaryLoad)>> {
        let mut out = Vec::new();
        let key = |k: Bound<'_, PyAny>, what: &str| -> PyResult<String> {
            k.extract()
                .map_err(|_| PyValueError::new_err(format!("{what}: keys are node set names")))
        };
        for (k, v) in displacements.into_iter().flat_map(|d| d.iter()) {
            let name = key(k, "displacements")?;
            let load = match v.extract::<[f64; 3]>() {
                Ok(d) => BoundaryLoad::Uniform(Vector3::from(d)),
                Err(_) => {
                    let rows = f64_rows(py, &v, 3, &format!("displacements['{name}']"))?;
                    BoundaryLoad::PerNode(rows.into_iter().map(Vector3::from).collect())
                }
            };
            out.push((name, load));
        }
        for (k, v) in surface.into_iter().flat_map(|d| d.iter()) {
            let name = key(k, "surface")?;
            let path = path_or_arrays(&v, &format!("surface['{name}']"), |t| {
                self.write_surface(py, &name, t)
            })?;
            out.push((name, BoundaryLoad::Surface(path)));
        }
        for (k, v) in landmarks.into_iter().flat_map(|d| d.iter()) {
            let name = key(k, "landmarks")?;
            let path = path_or_arrays(&v, &format!("landmarks['{name}']"), |t| {
                self.write_landmarks(py, &name, t)
            })?;
            out.push((name, BoundaryLoad::Landmarks(path)));
        }
        Ok(out)
    }

    /// The new scans of one `update` call: node set and points.
    fn scans(
        &self,
        py: Python<'_>,
        points: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Vec<(String, Vec<Point3<f64>>)>> {
        let mut out = Vec::new();
        for (k, v) in points.into_iter().flat_map(|d| d.iter()) {
            let name: String = k
                .extract()
                .map_err(|_| PyValueError::new_err("points: keys are node set names"))?;
            let rows = f64_rows(py, &v, 3, &format!("points['{name}']"))?;
            out.push((name, rows.into_iter().map(Point3::from).collect()));
        }
        Ok(out)
    }

    /// Writes the scratch file `file_name` with `write`; returns its path.
    fn scratch_file(
        &self,
        file_name: &str,
        write: impl FnOnce(&std::path::Path) -> std::io::Result<()>,
    ) -> PyResult<PathBuf> {
        let path = self.scratch.join(file_name);
        std::fs::create_dir_all(&self.scratch).and_then(|()| write(&path)).map_err(|e| {
            pyo3::exceptions::PyOSError::new_err(format!("{}: {e}", path.display()))
        })?;
        Ok(path)
    }

    /// Writes `(points, triangles)` as an OFF file in the scratch folder.
    fn write_surface(
        &self,
        py: Python<'_>,
        name: &str,
        t: &Bound<'_, PyTuple>,
    ) -> PyResult<PathBuf> {
        let what = format!("surface['{name}']");
        let points = f64_rows(py, &t.get_item(0)?, 3, &format!("{what} points"))?;
        let n = points.len();
        let tris = index_rows(py, &t.get_item(1)?, &[3], n, &format!("{what} triangles"))?;
        let surface = TriSurface::new(
            points.into_iter().map(Point3::from).collect(),
            tris.into_iter().map(|t| [t[0], t[1], t[2]]).collect(),
        );
        self.scratch_file(&format!("{name}-surface.off"), |path| {
            bs_mesh::io::write_surface(path, &surface).map_err(std::io::Error::other)
        })
    }

    /// Writes `(pre, intra)` landmark pairs as the CSV the scene's `landmarks` key reads.
    fn write_landmarks(
        &self,
        py: Python<'_>,
        name: &str,
        t: &Bound<'_, PyTuple>,
    ) -> PyResult<PathBuf> {
        let pre = f64_rows(py, &t.get_item(0)?, 3, &format!("landmarks['{name}'] pre"))?;
        let intra = f64_rows(py, &t.get_item(1)?, 3, &format!("landmarks['{name}'] intra"))?;
        if pre.len() != intra.len() {
            return Err(PyValueError::new_err(format!(
                "landmarks['{name}']: {} pre-operative and {} intra-operative points; give pairs",
                pre.len(),
                intra.len()
            )));
        }
        let mut text = String::from("x,y,z,x2,y2,z2\n");
        for (a, b) in pre.iter().zip(&intra) {
            text += &format!("{:?},{:?},{:?},{:?},{:?},{:?}\n", a[0], a[1], a[2], b[0], b[1], b[2]);
        }
        self.scratch_file(&format!("{name}-landmarks.csv"), |path| std::fs::write(path, text))
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
        Ok(Session { inner: Mutex::new(s), threads, scratch: scratch_dir() })
    }

    /// Solves new measurements warm from the last good state and verifies the result.
    /// `displacements={"SET": [dx, dy, dz]}` (uniform) or an (n, 3) array in the order of
    /// `set_nodes("SET")`; `surface={"SET": path or (points, triangles)}`;
    /// `landmarks={"SET": csv path or (pre, intra)}`: new values of prescribed boundaries
    /// (boundaries not named keep their last values); on the node set of a landmark
    /// `[[measurement]]` (`landmark_sets()`), its new pairs, fitted from the reference state
    /// with the session's preparation. `points={"SET": (m, 3) array}`: a new
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
    ) -> PyResult<RunResult> {
        let loads = self.loads(py, displacements, surface, landmarks)?;
        let scans = self.scans(py, points)?;
        // Landmarks on a landmark measurement's node set are fitted; on a boundary's, imposed.
        let measured = self.landmark_sets();
        let (fitted, loads): (Vec<_>, Vec<_>) = loads.into_iter().partition(|(name, load)| {
            matches!(load, BoundaryLoad::Landmarks(_)) && measured.contains(name)
        });
        if [!scans.is_empty(), !fitted.is_empty(), !loads.is_empty()].iter().filter(|&&x| x).count()
            > 1
        {
            return Err(PyValueError::new_err(
                "update: give new scans (points=), new landmarks of a [[measurement]] \
                 (landmarks= on its node set) or new boundary values (displacements=, \
                 surface=, landmarks=) in one call, not two of them; call update twice",
            ));
        }
        self.solve_with(py, progress.as_ref(), |s, observe| {
            let turned = gravity.map(|g| s.set_gravity(g)).transpose()?;
            let solved = if !scans.is_empty() {
                s.update_points(&scans, observe)
            } else if let Some((name, BoundaryLoad::Landmarks(file))) = fitted.first() {
                let files = bs_scene::scene::LandmarkFiles::Pairs(file.clone());
                s.update_landmarks(name, files, observe)
            } else if loads.is_empty() {
                s.solve(observe)
            } else {
                s.update(&loads, observe)
            };
            if let (Err(_), Some(previous)) = (&solved, turned) {
                s.set_gravity(previous).expect("the previous direction was accepted");
            }
            solved
        })
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
    ) -> PyResult<RunResult> {
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

impl Drop for Session {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.scratch);
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
    ) -> PyResult<RunResult> {
        let started = Instant::now();
        let mut callback_error: Option<PyErr> = None;
        let outcome = py.detach(|| {
            with_threads(self.threads, || {
                let threads = rayon::current_num_threads();
                let mut s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
                let mut observe = observer(progress, &mut callback_error);
                let solved = call(&mut s, &mut observe)?;
                let ctx = RunContext { total_seconds: started.elapsed().as_secs_f64(), threads };
                Ok::<_, SceneError>(RunResult::new(s.run(), solved, ctx))
            })
        });
        let result = outcome.map_err(PyValueError::new_err)?.map_err(|e| scene_err(py, e))?;
        match callback_error {
            Some(e) => Err(e),
            None => Ok(result),
        }
    }
}
