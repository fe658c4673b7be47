//! Run verdicts: how a study's run ended — a valid result, a typed guard that stopped it
//! before anything was written, or (the defect every study looks for) a result returned as
//! if valid that is not.

use crate::study::{Failure, Outcome};

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// A valid result.
    Converged,
    /// Stopped with a typed error before writing anything: the guard's name.
    Guard(String),
    /// A result that is not valid (the reason), returned as if it were.
    Silent(String),
    /// Not run by us (CalculiX's stored outcome is shown as text).
    External(String),
}

/// Classifies a variant's result. A returned result must be finite, have no inverted
/// element and leave no slave outside the skull beyond the tolerance; otherwise the run
/// failed silently.
pub fn classify(result: &Result<Outcome, Failure>, tolerance: f64) -> Verdict {
    match result {
        Err(Failure::Solve(e)) => Verdict::Guard(e.kind().into()),
        Err(Failure::Check(e)) => Verdict::Guard(e.kind().into()),
        Err(Failure::Setup(_)) => Verdict::Guard("SceneCheck".into()),
        Ok(o) => {
            if o.displacements.iter().any(|u| !u.iter().all(|x| x.is_finite())) {
                Verdict::Silent("non-finite displacement".into())
            } else if o.min_volume_ratio.is_nan() || o.min_volume_ratio <= 0.0 {
                Verdict::Silent(format!("inverted element (J = {:.2e})", o.min_volume_ratio))
            } else if o.max_penetration_after > tolerance {
                Verdict::Silent(format!("node outside by {:.2e}", o.max_penetration_after))
            } else {
                Verdict::Converged
            }
        }
    }
}

impl Verdict {
    /// The verdict in words.
    pub fn text(&self) -> String {
        match self {
            Verdict::Converged => "converged".into(),
            Verdict::Guard(g) => format!("guard: {g}"),
            Verdict::Silent(why) => format!("SILENT: {why}"),
            Verdict::External(s) => s.clone(),
        }
    }
}
