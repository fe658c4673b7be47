//! A scan fitted without `[gravity] estimate` whose pull cannot be carried: when the scene
//! without its data converges, the answer is that prior's, with the reason the data could
//! not be used (the measurement and the element its pull inverts); the run does not fail.

use bs_dr::{Progress, Solution, WarmStart};

use crate::SceneError;
use crate::compose::Composed;
use crate::prepare::Prepared;
use crate::solve::{SolveSettings, solve_composed_from};

/// What a solve with the data gave: its answer and largest penetration, and, when the data
/// could not be used, why (the answer is then the prior's).
#[derive(Debug)]
pub(crate) struct Fitted {
    pub solution: Solution,
    pub penetration: f64,
    pub unused: Option<String>,
}

/// Solves `c` with its data terms from `warm`. When that fails and `c` has data, the same
/// scene without them is solved from `warm`; if it converges its answer is returned with the
/// reason the data could not be used, otherwise the first failure (as an imposed boundary
/// would explain it). The data terms stay in `c` either way.
pub(crate) fn solve_or_prior(
    p: &Prepared,
    c: &mut Composed,
    settings: &SolveSettings,
    warm: Option<WarmStart<'_>>,
    observer: &mut dyn FnMut(&Progress),
) -> Result<Fitted, SceneError> {
    let err = match solve_composed_from(c, settings, warm, observer) {
        Ok((solution, penetration)) => return Ok(Fitted { solution, penetration, unused: None }),
        Err(e) if c.fit.is_some() => e,
        Err(e) => return Err(crate::imposed::explain(p.imposed(), e)),
    };
    let data = c.fit.take();
    let prior = solve_composed_from(c, settings, warm, observer);
    c.fit = data;
    match prior {
        Ok((solution, penetration)) => Ok(Fitted {
            solution,
            penetration,
            unused: Some(format!(
                "{}; the answer is the prior's (the scene without its measurements)",
                super::failure::pull_failure(p, &err)
            )),
        }),
        Err(_) => Err(crate::imposed::explain(p.imposed(), err)),
    }
}
