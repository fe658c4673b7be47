//! The guard of Dynamic Relaxation: what stops a run that cannot converge, as a typed error
//! naming the step and the fix.
//!
//! * Non-finite displacements or step changes: [`DrError::NotFinite`].
//! * Alternating growth, the signature of a time step above critical: `Δu_k · Δu_{k−1} <
//!   −½ |Δu_k||Δu_{k−1}|` and `|Δu_k| > 1.25 |Δu_{k−1}|` for 4 steps in a row:
//!   [`DrError::Unstable`] with the mean growth factor. An inverted element after two such
//!   steps is reported as the instability that caused it.
//! * `max|u|` beyond `divergence_factor × load scale`: [`DrError::Diverged`].

use bs_mesh::Vector3;

use super::outcome::DrError;
use crate::assembly::Inversion;

/// Growth of `|Δu|` per step that counts.
const GROWTH_RATIO: f64 = 1.25;
/// Steps of alternating growth in a row that stop the run.
const GROWTH_STEPS: usize = 4;

/// What one step changed, over the free DOFs: `max|Δu_k|`, `Δu_k · Δu_{k−1}`, `|Δu_k|²`,
/// `|Δu_{k−1}|²`, and the largest nodal displacement after it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StepChange {
    pub maxd: f64,
    pub dot: f64,
    pub nk: f64,
    pub nk1: f64,
    pub maxu: f64,
}

impl StepChange {
    /// The change from `u_prev → u` to `u → u_next`.
    pub(crate) fn of(
        free: &[usize],
        u_next: &[Vector3<f64>],
        u: &[Vector3<f64>],
        u_prev: &[Vector3<f64>],
    ) -> Self {
        let mut maxd = 0.0f64;
        let (mut dot, mut nk, mut nk1) = (0.0, 0.0, 0.0);
        for &d in free {
            let (a, c) = (d / 3, d % 3);
            let dk = u_next[a][c] - u[a][c];
            let dk1 = u[a][c] - u_prev[a][c];
            maxd = maxd.max(dk.abs());
            dot += dk * dk1;
            nk += dk * dk;
            nk1 += dk1 * dk1;
        }
        let maxu = u_next.iter().fold(0.0f64, |acc, v| acc.max(v.norm()));
        StepChange { maxd, dot, nk, nk1, maxu }
    }
}

/// The guard's state: the current run of alternating growth.
#[derive(Debug, Clone)]
pub(crate) struct GrowthGuard {
    step_fraction: f64,
    limit: f64,
    count: usize,
    log: f64,
}

impl GrowthGuard {
    /// A guard for a run with `step_fraction` whose displacements may not exceed `limit`.
    pub(crate) fn new(step_fraction: f64, limit: f64) -> Self {
        GrowthGuard { step_fraction, limit, count: 0, log: 0.0 }
    }

    fn unstable(&self, step: usize) -> DrError {
        DrError::Unstable {
            step,
            growth: (self.log / self.count as f64).exp(),
            steps: self.count,
            step_fraction: self.step_fraction,
        }
    }

    /// The error for an element found inverted at `step`: the instability if growth was
    /// already under way, else the inversion.
    pub(crate) fn inverted(&self, step: usize, inv: Inversion) -> DrError {
        if self.count >= 2 { self.unstable(step) } else { DrError::inverted(step, inv) }
    }

    /// Checks the change `c` of `step`.
    pub(crate) fn check(&mut self, step: usize, c: &StepChange) -> Result<(), DrError> {
        if !(c.maxd.is_finite() && c.maxu.is_finite() && c.nk.is_finite()) {
            return Err(DrError::NotFinite { step });
        }
        if c.nk1 > 0.0
            && c.dot < -0.5 * (c.nk * c.nk1).sqrt()
            && c.nk > GROWTH_RATIO * GROWTH_RATIO * c.nk1
        {
            self.count += 1;
            self.log += 0.5 * (c.nk / c.nk1).ln();
            if self.count >= GROWTH_STEPS {
                return Err(self.unstable(step));
            }
        } else {
            self.count = 0;
            self.log = 0.0;
        }
        if c.maxu > self.limit {
            return Err(DrError::Diverged { step, max_displacement: c.maxu, limit: self.limit });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A change of norm `n` reversing a previous change of norm `prev`.
    fn flip(n: f64, prev: f64) -> StepChange {
        StepChange { maxd: n, dot: -n * prev, nk: n * n, nk1: prev * prev, maxu: 1.0 }
    }

    #[test]
    fn alternating_growth_stops_after_four_steps_with_its_rate() {
        let mut g = GrowthGuard::new(1.3, 100.0);
        let mut prev = 1.0;
        for step in 1..=3 {
            assert_eq!(g.check(step, &flip(1.5 * prev, prev)), Ok(()));
            prev *= 1.5;
        }
        match g.check(4, &flip(1.5 * prev, prev)) {
            Err(DrError::Unstable { step: 4, growth, steps: 4, step_fraction }) => {
                assert!((growth - 1.5).abs() < 1e-12 && step_fraction == 1.3, "{growth}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_calm_step_resets_the_count_and_slow_growth_does_not_count() {
        let mut g = GrowthGuard::new(0.8, 100.0);
        for step in 1..=3 {
            g.check(step, &flip(2.0, 1.0)).unwrap();
        }
        // Same direction: not alternating.
        let calm = StepChange { maxd: 2.0, dot: 2.0, nk: 4.0, nk1: 1.0, maxu: 1.0 };
        g.check(4, &calm).unwrap();
        for step in 5..=7 {
            g.check(step, &flip(2.0, 1.0)).unwrap();
        }
        // Alternating but growing by 1.2 < 1.25: not counted, and it resets.
        g.check(8, &flip(1.2, 1.0)).unwrap();
        g.check(9, &flip(2.0, 1.0)).unwrap();
        let inv = Inversion { element: 3, element_id: 4, jacobian: -0.1 };
        assert!(matches!(g.inverted(10, inv), DrError::ElementInverted { element: 3, .. }));
        g.check(10, &flip(2.0, 1.0)).unwrap();
        assert!(matches!(g.inverted(11, inv), DrError::Unstable { step: 11, steps: 2, .. }));
    }

    #[test]
    fn non_finite_and_runaway_displacements_stop_the_run() {
        let mut g = GrowthGuard::new(0.8, 10.0);
        let nan = StepChange { maxd: f64::NAN, dot: 0.0, nk: 0.0, nk1: 0.0, maxu: 0.0 };
        assert_eq!(g.check(5, &nan), Err(DrError::NotFinite { step: 5 }));
        let far = StepChange { maxd: 1.0, dot: 1.0, nk: 1.0, nk1: 1.0, maxu: 11.0 };
        assert_eq!(
            g.check(6, &far),
            Err(DrError::Diverged { step: 6, max_displacement: 11.0, limit: 10.0 })
        );
    }

    #[test]
    fn step_change_reads_the_free_dofs_only() {
        let u_prev = vec![Vector3::new(0.0, 0.0, 0.0); 2];
        let u = vec![Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 5.0, 0.0)];
        let u_next = vec![Vector3::new(0.5, 0.0, 0.0), Vector3::new(0.0, 9.0, 0.0)];
        // DOF 4 (node 1, y) is prescribed: not counted.
        let c = StepChange::of(&[0, 1, 2, 3, 5], &u_next, &u, &u_prev);
        assert_eq!((c.maxd, c.dot, c.nk, c.nk1, c.maxu), (0.5, -0.5, 0.25, 1.0, 9.0));
    }
}
