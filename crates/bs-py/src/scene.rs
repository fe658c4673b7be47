//! `Scene`: a scene from a file or from arrays; check and run.

use std::path::{Path, PathBuf};
use std::time::Instant;

use bs_mesh::{Element, Mesh, Point3};
use bs_scene::output::RunContext;
use bs_scene::{Prepared, Run, SceneError};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{
    f64_rows, from_json, index_rows, index_sets, observer, scene_err, skull_of, with_threads,
};
use crate::result::VerifiedRun;

/// A brain-shift scene: a mesh with materials, boundary conditions and optionally a skull.
#[pyclass(module = "brainshift", frozen)]
pub(crate) struct Scene {
    pub(crate) prepared: Prepared,
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
        self.prepared.scene.space.name()
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
    ) -> PyResult<VerifiedRun> {
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
        Ok(VerifiedRun::new(&run, solved, ctx))
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
