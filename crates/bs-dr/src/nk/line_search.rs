//! The line search: the first trial step is the largest (at most the full Newton step) that
//! keeps every element's volume ratio above a fraction of its current value
//! ([`Model::step_bound`](crate::Model::step_bound), exact per element), so no iterate
//! inverts an element; then backtracking by halves on the natural residual
//! ([`super::merit`]) with an Armijo sufficient-decrease test.
//!
//! A step that applies prescribed displacement (the first of a load level without a
//! predictor) is accepted at its first trial: the residual of a new load is not comparable
//! with the old one. When no trial decreases the residual, the best one is taken: near the
//! solution the surface features of contact nodes can cycle, and a damped step breaks the
//! cycle where a rejected one would stop.
//!
//! A full step whose residual rose only at a few contact nodes, each by a jump larger than
//! the whole residual before the step, is accepted when the rest of the residual decreased
//! enough. On a faceted skull the closest point of a trial point jumps from one face to its
//! neighbour where the trial point crosses the set of points equidistant from both: that
//! node's term is discontinuous along the line, and shorter steps only approach the jump.
//! On the 852k-tet brain one node's closest point jumped 0.06 mm to the next face, and
//! three iterations took α = 1/4, 1/8, 1/16 in front of it before the best trial, the full
//! step, was taken. The next iteration's active set puts the node on its new face.

use super::merit::Merit;
use super::outcome::NewtonKrylovError;
use super::params::LineSearchParams;

/// How a line search ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Outcome {
    /// A trial with sufficient decrease (or the load step's first trial).
    Accepted { alpha: f64, merit: f64 },
    /// No trial decreased the residual enough; the one with the smallest residual.
    Best { alpha: f64, merit: f64 },
    /// No trial could be evaluated (every one inverted an element or was not finite).
    Failed,
}

impl Outcome {
    /// The step taken and its residual, if any.
    pub(crate) fn step(&self) -> Option<(f64, f64)> {
        match *self {
            Outcome::Accepted { alpha, merit } | Outcome::Best { alpha, merit } => {
                Some((alpha, merit))
            }
            Outcome::Failed => None,
        }
    }
}

/// Runs the line search from the first trial `first` (already capped by the element
/// bound) on the residual `phi` of the current iterate. `eval(α)` computes the trial's
/// residual, with the contact nodes whose term exceeds `phi` counted apart (`None` if the
/// trial is not admissible). `accept_first`: a load step. `max_jumps`: how many such nodes
/// a full step may carry (see the module documentation). Returns the outcome and the last
/// α evaluated (the trial state the caller holds).
pub(crate) fn search(
    p: &LineSearchParams,
    first: f64,
    phi: f64,
    accept_first: bool,
    max_jumps: usize,
    eval: &mut dyn FnMut(f64) -> Result<Option<Merit>, NewtonKrylovError>,
) -> Result<(Outcome, f64), NewtonKrylovError> {
    let mut alpha = first;
    let mut best: Option<(f64, f64)> = None; // (merit, alpha)
    let mut last = f64::NAN;
    while alpha >= first * p.min_fraction && alpha > 0.0 {
        last = alpha;
        if let Some(trial) = eval(alpha)? {
            let m = trial.value;
            let enough = |m: f64| m <= (1.0 - p.armijo * alpha) * phi;
            let jumped = alpha == first
                && (1..=max_jumps).contains(&trial.jumps)
                && enough(trial.without_jumps);
            if accept_first || !phi.is_finite() || enough(m) || jumped {
                return Ok((Outcome::Accepted { alpha, merit: m }, last));
            }
            if best.is_none_or(|(b, _)| m < b) {
                best = Some((m, alpha));
            }
        }
        alpha *= 0.5;
    }
    Ok(match best {
        Some((merit, alpha)) => (Outcome::Best { alpha, merit }, last),
        None => (Outcome::Failed, last),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(first: f64, phi: f64, load: bool, f: impl Fn(f64) -> Option<f64>) -> (Outcome, f64) {
        let p = LineSearchParams::default();
        search(&p, first, phi, load, 0, &mut |a| Ok(f(a).map(Merit::plain))).unwrap()
    }

    #[test]
    fn a_full_step_that_decreases_the_residual_is_taken() {
        let (o, last) = run(1.0, 1.0, false, |a| Some(1.0 - 0.5 * a));
        assert_eq!(o, Outcome::Accepted { alpha: 1.0, merit: 0.5 });
        assert_eq!(last, 1.0);
    }

    #[test]
    fn backtracking_halves_until_the_residual_decreases_enough() {
        // Residual (1 − a)² + 4a² ... decreases only for small steps: φ(a) = 1 − a + 3a².
        let (o, _) = run(1.0, 1.0, false, |a| Some(1.0 - a + 3.0 * a * a));
        // a = 1: 3; 0.5: 1.25; 0.25: 0.9375 ≤ 1 − 1e-4·0.25 → accepted.
        assert_eq!(o, Outcome::Accepted { alpha: 0.25, merit: 0.9375 });
    }

    #[test]
    fn without_decrease_the_best_trial_is_taken_and_inadmissible_ones_are_skipped() {
        let (o, last) = run(0.5, 1.0, false, |a| if a > 0.2 { None } else { Some(1.0 + a) });
        // 0.5, 0.25 inadmissible; 0.125 → 1.125, 0.0625 → 1.0625 (best), then stop at 1/16.
        assert_eq!(o, Outcome::Best { alpha: 0.03125, merit: 1.03125 });
        assert_eq!(last, 0.03125);
        let (o, _) = run(1.0, 1.0, false, |_| None);
        assert_eq!(o, Outcome::Failed);
    }

    #[test]
    fn a_load_step_is_accepted_at_its_first_admissible_trial() {
        let (o, _) = run(0.6, 1.0, true, |a| Some(10.0 + a));
        assert_eq!(o, Outcome::Accepted { alpha: 0.6, merit: 10.6 });
    }

    /// A trial whose residual is `rest` away from one node and `node` at it.
    fn jumped(rest: f64, node: f64, jumps: usize) -> Merit {
        Merit { value: rest.hypot(node), without_jumps: rest, jumps }
    }

    #[test]
    fn a_full_step_rejected_only_for_a_few_jumping_contact_nodes_is_taken() {
        let p = LineSearchParams::default();
        // The 852k-tet brain's iteration 12: the residual 2.37e-2 before; the full step
        // leaves 3.2e-3 except one node's 6.19e-2 (its closest point jumped).
        let mut eval = |_: f64| Ok(Some(jumped(3.2e-3, 6.19e-2, 1)));
        let (o, _) = search(&p, 1.0, 2.37e-2, false, 1, &mut eval).unwrap();
        assert_eq!(o, Outcome::Accepted { alpha: 1.0, merit: 3.2e-3f64.hypot(6.19e-2) });
        // More jumping nodes than allowed, or a rest that did not decrease enough: the
        // ordinary backtracking (every trial here is the same, so the best is the first).
        let (o, _) =
            search(&p, 1.0, 2.37e-2, false, 1, &mut |_| Ok(Some(jumped(3.2e-3, 6.19e-2, 2))))
                .unwrap();
        assert!(matches!(o, Outcome::Best { alpha, .. } if alpha == 1.0), "{o:?}");
        let (o, _) =
            search(&p, 1.0, 2.37e-2, false, 1, &mut |_| Ok(Some(jumped(2.4e-2, 6.19e-2, 1))))
                .unwrap();
        assert!(matches!(o, Outcome::Best { .. }), "{o:?}");
        // Only the first trial may jump: a shorter one is judged on its whole residual.
        let mut eval =
            |a: f64| Ok(Some(if a < 1.0 { jumped(3.2e-3, 6.19e-2, 1) } else { Merit::plain(1.0) }));
        let (o, _) = search(&p, 1.0, 2.37e-2, false, 1, &mut eval).unwrap();
        assert!(matches!(o, Outcome::Best { alpha, .. } if alpha == 0.5), "{o:?}");
    }
}
