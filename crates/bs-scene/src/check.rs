//! Checking a scene without solving it: everything `run` does before the solve (reading,
//! resolution, memory, composition, the initial gap), and what a user should know about it.
//! A scene that passes fails in `run` only for numerical reasons.

use std::path::Path;

use crate::SceneError;
use crate::compose::{Composed, compose};
use crate::findings::Findings;
use crate::prepare::Prepared;

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
    let composed = compose(&prepared)?;
    let initial_gap = composed.check_initial_gap(&prepared)?;
    let memory_estimate = crate::memory::estimate(&prepared);
    let advice = Findings::embedded().map(|f| crate::advice::advise(&prepared, &f));
    Ok(Checked { prepared, composed, initial_gap, memory_estimate, advice })
}
