//! Which fit a scene's measurements ask for, in one place for runs and sessions: landmarks
//! through their node set (with gravity's unknowns when the scene estimates them), a scan
//! with gravity's unknowns estimated, or the data terms solved with the model (falling
//! back to the prior's answer when their pull cannot be carried).

use bs_dr::{Progress, Solution, WarmStart};

use crate::SceneError;
use crate::compose::Composed;
use crate::estimate::GravityReport;
use crate::prepare::Prepared;
use crate::solve::SolveSettings;

/// What the solve with the measurements gave.
#[derive(Debug)]
pub(crate) struct Answer {
    pub solution: Solution,
    /// Largest penetration any slave had before it was corrected.
    pub penetration: f64,
    /// What was estimated of gravity (`None`: nothing; the scene's own is reported).
    pub gravity: Option<GravityReport>,
    /// Why the data could not be used, when they could not (the answer is the prior's).
    pub unused: Option<String>,
}

/// Solves `p`'s composition `c` with its measurements from `from` (the landmark fit takes
/// its state; an estimate of gravity starts from the scene's values each time).
pub(crate) fn solve_measured(
    p: &mut Prepared,
    c: &mut Composed,
    settings: &SolveSettings,
    from: Option<WarmStart<'_>>,
    observer: &mut dyn FnMut(&Progress),
) -> Result<Answer, SceneError> {
    if crate::landmark_fit::has_landmarks(p) {
        let warm = from.map(|w| w.state);
        let (solution, penetration, info) =
            crate::landmark_fit::solve(p, c, settings, warm, observer)?;
        return Ok(Answer { solution, penetration, gravity: info.gravity, unused: None });
    }
    if crate::estimate::estimates(p) {
        let (solution, penetration, g) = crate::estimate::solve(p, c, settings, observer)?;
        let unused = crate::estimate::unused_reason(Some(&g));
        return Ok(Answer { solution, penetration, gravity: Some(g), unused });
    }
    let f = super::fallback::solve_or_prior(p, c, settings, from, observer)?;
    Ok(Answer { solution: f.solution, penetration: f.penetration, gravity: None, unused: f.unused })
}
