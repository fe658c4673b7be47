//! Checking a scene without solving it: everything `run` does before the solve (reading,
//! resolution, memory, composition, the initial gap), and what a user should know about it.
//! A scene that passes fails in `run` only for numerical reasons.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::SceneError;
use crate::compose::{Composed, compose};
use crate::prepare::Prepared;
use crate::speed_accuracy::Findings;

/// A scene that can run, with what `brainshift check` reports about it.
#[derive(Debug)]
pub struct Checked {
    /// The scene with its files read and names resolved.
    pub prepared: Prepared,
    /// Model, loads and contact.
    pub composed: Composed,
    /// Smallest and largest initial brain–skull gap over the slave nodes (with contact).
    pub initial_gap: Option<(f64, f64)>,
    /// Estimated peak memory of a run (bytes).
    pub memory_estimate: f64,
    /// The advice of the speed-versus-accuracy findings, or why there is none.
    pub advice: Result<Vec<String>, String>,
}

/// Checks the scene at `path` as `run` would before solving.
pub fn check(path: &Path) -> Result<Checked, SceneError> {
    check_prepared(Prepared::load(path)?)
}

/// [`check`] for a scene already prepared (the Python bindings' scene from arrays).
pub fn check_prepared(prepared: Prepared) -> Result<Checked, SceneError> {
    crate::memory::require_fits(&prepared, crate::memory::available())?;
    // `[uncertainty] held_out` is read only by `run --uncertainty`: its mistakes found here.
    crate::uncertainty::held_out::HeldOut::read(&prepared)?;
    let composed = compose(&prepared)?;
    let initial_gap = composed.check_initial_gap(&prepared)?;
    let memory_estimate = crate::memory::estimate(&prepared);
    let advice = Findings::embedded().map(|f| crate::advice::advise(&prepared, &f));
    Ok(Checked { prepared, composed, initial_gap, memory_estimate, advice })
}

/// What `brainshift check` reports about a scene that can run: the one typed report the
/// command line prints (as text, or as JSON with `--json`) and the Python bindings return
/// as a dict. Names as the scene file spells them; times in seconds, sizes in bytes,
/// lengths in the scene's unit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckReport {
    /// The scene file (`<arrays>` for a scene built from arrays) and its mesh file.
    pub scene: PathBuf,
    pub mesh: PathBuf,
    /// Nodes, linear tetrahedra and hexahedra of the mesh.
    pub nodes: usize,
    pub tet4: usize,
    pub hex8: usize,
    /// The element technology and the length unit.
    pub element: String,
    pub units: String,
    /// One entry per `[[region]]`.
    pub regions: Vec<RegionReport>,
    /// Nodes with every component held at zero; nodes with a prescribed non-zero component;
    /// contact (slave) nodes.
    pub fixed_nodes: usize,
    pub moved_nodes: usize,
    pub slave_nodes: usize,
    /// One line per load the scene applies beyond its boundaries (gravity, resection).
    pub loads: Vec<String>,
    /// The skull, when the scene has contact.
    pub skull: Option<SkullReport>,
    /// Smallest and largest initial brain–skull gap over the slave nodes.
    pub initial_gap: Option<(f64, f64)>,
    /// The solver and its tolerance.
    pub solver: String,
    pub tolerance: f64,
    /// The explicit stable time step (s) and the element that sets it (its id in the file).
    pub stable_time_step: f64,
    pub smallest_element: u64,
    /// Estimated peak memory of a run.
    pub memory_estimate_bytes: f64,
    /// What the user should know.
    pub warnings: Vec<String>,
    /// How much model the scene needs (the speed-versus-accuracy findings), or why there is
    /// no advice (one line in parentheses).
    pub advice: Vec<String>,
}

/// A region of a [`CheckReport`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegionReport {
    pub elset: String,
    pub elements: usize,
    /// The constitutive model (`neo-hookean`, `svk`, `ogden`) and its small-strain moduli (Pa).
    pub model: String,
    pub shear_modulus: f64,
    pub bulk_modulus: f64,
}

/// The skull of a [`CheckReport`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkullReport {
    pub file: PathBuf,
    pub vertices: usize,
    pub triangles: usize,
    /// The contact algorithm.
    pub algorithm: String,
}

impl Checked {
    /// The report of the check.
    pub fn report(&self) -> CheckReport {
        let p = &self.prepared;
        let (tet4, hex8) = p.mesh.count_by_kind();
        let regions = p
            .scene
            .regions
            .iter()
            .enumerate()
            .map(|(r, region)| {
                let m = region.material.moduli().expect("checked at parse time");
                RegionReport {
                    elset: region.elset.clone(),
                    elements: p.region_of_element.iter().filter(|&&x| x == r).count(),
                    model: region.material.model.to_string(),
                    shear_modulus: m.mu,
                    bulk_modulus: m.kappa,
                }
            })
            .collect();
        let skull = match (&p.skull, &p.scene.contact) {
            (Some(s), Some(c)) => Some(SkullReport {
                file: c.skull.clone(),
                vertices: s.vertices.len(),
                triangles: s.triangles.len(),
                algorithm: c.algorithm.to_string(),
            }),
            _ => None,
        };
        let (dt, e) = self.composed.model.critical_time_step();
        CheckReport {
            scene: p.path.clone(),
            mesh: p.scene.mesh.file.clone(),
            nodes: p.mesh.nodes.len(),
            tet4,
            hex8,
            element: p.element.to_string(),
            units: p.scene.units.symbol().to_string(),
            regions,
            fixed_nodes: p.prescribed.iter().filter(|c| c.iter().all(|v| *v == Some(0.0))).count(),
            moved_nodes: p
                .prescribed
                .iter()
                .filter(|c| c.iter().flatten().any(|v| *v != 0.0))
                .count(),
            slave_nodes: self.composed.slaves.len(),
            loads: p.loads.clone(),
            skull,
            initial_gap: self.initial_gap,
            solver: p.scene.solver.kind.to_string(),
            tolerance: p.scene.solver.tolerance,
            stable_time_step: dt * p.scene.units.metres(),
            smallest_element: p.mesh.element_ids[e],
            memory_estimate_bytes: self.memory_estimate,
            warnings: p.warnings.clone(),
            advice: match &self.advice {
                Ok(lines) => lines.clone(),
                Err(e) => vec![format!("(no advice: {e})")],
            },
        }
    }
}
