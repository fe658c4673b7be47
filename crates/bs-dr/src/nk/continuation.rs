//! Load continuation: the prescribed displacements are applied in increments of the load
//! fraction λ, each solved to equilibrium before the next. Increments grow after easy
//! levels and are cut back and retried after a failed one (FEBio retries a failed step with
//! a smaller increment, Abaqus cuts a diverging increment to 25 %); the next level starts
//! from a secant predictor through the last two converged states (Abaqus extrapolates the
//! same way). An easy load is one increment, the whole load.

use super::params::ContinuationParams;

/// The state of the continuation.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Continuation {
    p: ContinuationParams,
    /// λ of the last converged level.
    done: f64,
    /// λ of the level before it, once there is one.
    previous: Option<f64>,
    increment: f64,
    /// Failed attempts at the current level.
    cutbacks: usize,
    /// Converged levels and failed attempts in all.
    pub levels: usize,
    pub failures: usize,
}

/// Why no further attempt is made at a level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Exhausted {
    /// λ reached.
    pub reached: f64,
    /// The last increment tried.
    pub increment: f64,
}

impl Continuation {
    pub(crate) fn new(p: ContinuationParams) -> Self {
        Continuation {
            p,
            done: 0.0,
            previous: None,
            increment: p.initial_increment,
            cutbacks: 0,
            levels: 0,
            failures: 0,
        }
    }

    /// λ of the last converged level.
    pub(crate) fn done(&self) -> f64 {
        self.done
    }

    pub(crate) fn finished(&self) -> bool {
        self.done >= 1.0
    }

    /// λ of the next level.
    pub(crate) fn target(&self) -> f64 {
        let t = self.done + self.increment;
        if t >= 1.0 - 1e-9 { 1.0 } else { t }
    }

    /// The secant predictor's factor for `target`: the next state is predicted as
    /// `u_done + s (u_done − u_previous)`, with `s = (target − done) / (done − previous)`.
    /// `None` before two levels exist (the first Newton step is then the tangent predictor).
    pub(crate) fn extrapolation(&self, target: f64) -> Option<f64> {
        let prev = self.previous?;
        let last = self.done - prev;
        (last > 0.0).then(|| (target - self.done) / last)
    }

    /// A level converged at `reached` (at most the target: a first step that would crush an
    /// element stops short) after `iterations` Newton iterations: the next increment grows
    /// after an easy level, shrinks after a hard one.
    pub(crate) fn accept(&mut self, reached: f64, iterations: usize) {
        let taken = reached - self.done;
        self.previous = Some(self.done);
        self.done = if reached >= 1.0 - 1e-12 { 1.0 } else { reached };
        self.cutbacks = 0;
        self.levels += 1;
        let factor = if iterations <= self.p.easy_iterations {
            self.p.growth
        } else if iterations > self.p.hard_iterations {
            1.0 / self.p.growth
        } else {
            1.0
        };
        self.increment = (taken * factor).max(f64::MIN_POSITIVE);
    }

    /// A level failed: the next attempt takes a smaller increment from the last converged
    /// state. `Err` when the attempts at this level are used up.
    pub(crate) fn cut_back(&mut self) -> Result<(), Exhausted> {
        self.failures += 1;
        self.cutbacks += 1;
        let tried = self.target() - self.done;
        self.increment = tried * self.p.cutback;
        if self.cutbacks > self.p.max_cutbacks {
            return Err(Exhausted { reached: self.done, increment: tried });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_easy_load_is_one_increment() {
        let mut c = Continuation::new(ContinuationParams::default());
        assert_eq!(c.target(), 1.0);
        assert_eq!(c.extrapolation(1.0), None);
        c.accept(1.0, 12);
        assert!(c.finished());
        assert_eq!(c.levels, 1);
    }

    #[test]
    fn increments_are_cut_back_then_grow_and_the_predictor_extrapolates_the_last_two() {
        let mut c = Continuation::new(ContinuationParams::default());
        c.cut_back().unwrap();
        assert_eq!(c.target(), 0.25);
        c.accept(0.25, 4); // easy: the next increment doubles
        assert_eq!(c.target(), 0.75);
        // (0.75 − 0.25) / (0.25 − 0) = 2
        assert_eq!(c.extrapolation(0.75), Some(2.0));
        c.accept(0.75, 20); // hard: halves
        assert_eq!(c.target(), 1.0);
        assert_eq!(c.extrapolation(1.0), Some(0.5));
        c.accept(1.0, 10);
        assert!(c.finished());
        assert_eq!((c.levels, c.failures), (3, 1));
    }

    #[test]
    fn a_first_step_that_stops_short_sets_the_increment_taken() {
        let mut c = Continuation::new(ContinuationParams::default());
        c.accept(0.3, 10); // asked 1.0, the capped step reached 0.3
        assert!((c.target() - 0.6).abs() < 1e-15);
    }

    #[test]
    fn cutbacks_are_limited_per_level() {
        let p = ContinuationParams { max_cutbacks: 2, ..Default::default() };
        let mut c = Continuation::new(p);
        c.cut_back().unwrap();
        c.cut_back().unwrap();
        let e = c.cut_back().unwrap_err();
        assert_eq!(e.reached, 0.0);
        assert!((e.increment - 0.0625).abs() < 1e-15);
        // A converged level resets the count.
        let mut c = Continuation::new(p);
        c.cut_back().unwrap();
        c.cut_back().unwrap();
        c.accept(c.target(), 3);
        c.cut_back().unwrap();
    }
}
