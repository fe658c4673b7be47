//! When a load level is done: converged (the last correction below the level's tolerance
//! with the prescribed displacement applied, the active set settled and no node outside),
//! or failed (its iteration budget spent, or the residual no longer decreasing), which the
//! continuation answers with a smaller increment.

/// What the test needs from one iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Iteration {
    /// Last correction `max|Δu|` (length units).
    pub err: f64,
    /// Prescribed displacement still to apply at this level.
    pub loading: bool,
    /// This iteration applied load (its residual starts a new descent).
    pub loaded: bool,
    /// Contact nodes whose state changed in this iteration.
    pub changes: usize,
    /// Largest distance of a contact node outside the surface.
    pub penetration: f64,
    /// The natural residual after the step.
    pub phi: f64,
}

/// Why a level failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Failure {
    /// Its iteration budget after the last load step was spent.
    Budget,
    /// The residual did not decrease by 1 % in `stall_iterations` iterations.
    Stalled,
}

/// The verdict after an iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Verdict {
    Continue,
    Converged,
    Failed(Failure),
}

/// The convergence and failure test of one load level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Termination {
    tol: f64,
    budget: usize,
    stall: usize,
    iterations: usize,
    since_load: usize,
    best: f64,
    since_best: usize,
}

impl Termination {
    /// A level with tolerance `tol`, at most `budget` iterations after its last load step,
    /// failing after `stall` iterations without progress.
    pub(crate) fn new(tol: f64, budget: usize, stall: usize) -> Self {
        Termination {
            tol,
            budget,
            stall,
            iterations: 0,
            since_load: 0,
            best: f64::INFINITY,
            since_best: 0,
        }
    }

    /// Iterations so far at this level.
    pub(crate) fn iterations(&self) -> usize {
        self.iterations
    }

    pub(crate) fn check(&mut self, it: &Iteration) -> Verdict {
        self.iterations += 1;
        self.since_load = if it.loaded { 0 } else { self.since_load + 1 };
        if it.err < self.tol && !it.loading && it.changes == 0 && it.penetration < self.tol {
            return Verdict::Converged;
        }
        if it.loaded || it.phi < 0.99 * self.best {
            self.best = it.phi;
            self.since_best = 0;
        } else {
            self.since_best += 1;
        }
        if self.since_best >= self.stall {
            Verdict::Failed(Failure::Stalled)
        } else if self.since_load >= self.budget {
            Verdict::Failed(Failure::Budget)
        } else {
            Verdict::Continue
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn it(err: f64, phi: f64) -> Iteration {
        Iteration { err, loading: false, loaded: false, changes: 0, penetration: 0.0, phi }
    }

    #[test]
    fn converges_only_when_every_condition_holds() {
        let mut t = Termination::new(1e-3, 30, 8);
        assert_eq!(t.check(&Iteration { loading: true, ..it(1e-4, 1.0) }), Verdict::Continue);
        assert_eq!(t.check(&Iteration { changes: 1, ..it(1e-4, 0.5) }), Verdict::Continue);
        assert_eq!(t.check(&Iteration { penetration: 2e-3, ..it(1e-4, 0.2) }), Verdict::Continue);
        assert_eq!(t.check(&it(2e-3, 0.1)), Verdict::Continue);
        assert_eq!(t.check(&it(5e-4, 0.05)), Verdict::Converged);
        assert_eq!(t.iterations(), 5);
    }

    #[test]
    fn a_residual_that_stops_decreasing_fails_the_level() {
        let mut t = Termination::new(1e-3, 30, 3);
        assert_eq!(t.check(&it(1.0, 10.0)), Verdict::Continue);
        assert_eq!(t.check(&it(1.0, 9.95)), Verdict::Continue); // < 1 %
        assert_eq!(t.check(&it(1.0, 9.96)), Verdict::Continue);
        assert_eq!(t.check(&it(1.0, 9.99)), Verdict::Failed(Failure::Stalled));
    }

    #[test]
    fn the_budget_ends_a_level_that_still_progresses_but_load_steps_restart_it() {
        let mut t = Termination::new(1e-3, 3, 8);
        assert_eq!(t.check(&it(1.0, 3.0)), Verdict::Continue);
        assert_eq!(t.check(&it(1.0, 2.0)), Verdict::Continue);
        let loaded = Iteration { loaded: true, loading: true, ..it(1.0, 9.0) };
        assert_eq!(t.check(&loaded), Verdict::Continue);
        assert_eq!(t.check(&it(1.0, 1.0)), Verdict::Continue);
        assert_eq!(t.check(&it(1.0, 0.5)), Verdict::Continue);
        assert_eq!(t.check(&it(1.0, 0.2)), Verdict::Failed(Failure::Budget));
    }

    #[test]
    fn a_load_step_starts_a_new_descent() {
        let mut t = Termination::new(1e-3, 30, 2);
        assert_eq!(t.check(&it(1.0, 1.0)), Verdict::Continue);
        // A load step raises the residual: not a stall.
        let loaded = Iteration { loaded: true, loading: true, ..it(1.0, 50.0) };
        assert_eq!(t.check(&loaded), Verdict::Continue);
        assert_eq!(t.check(&it(1.0, 40.0)), Verdict::Continue);
        assert_eq!(t.check(&it(1.0, 39.9)), Verdict::Continue);
        assert_eq!(t.check(&it(1.0, 39.8)), Verdict::Failed(Failure::Stalled));
    }
}
