//! The forcing term: how accurately each Newton iteration's linear system is solved
//! (Eisenstat & Walker 1996, choice 2, safeguarded), loosened while the contact active set
//! still moves and never tighter than the tolerance needs.

/// Eisenstat–Walker forcing with the solver's bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Forcing {
    eta: f64,
    /// `eta` with the tolerance term sized by the predicted next correction: used while the
    /// active set stands still.
    settled: f64,
    min: f64,
    max: f64,
    active_set: f64,
}

impl Forcing {
    /// Bounds `[min, max]` and the relative residual used while the active set moves.
    pub(crate) fn new(min: f64, max: f64, active_set: f64) -> Self {
        Forcing { eta: max, settled: max, min, max, active_set }
    }

    /// The relative residual asked of the next linear solve. While prescribed displacement
    /// is still being applied the step carries it into the mesh and must be accurate, or the
    /// elements next to the prescribed nodes take the whole jump; while more than 1 % of the
    /// `contact_nodes` changed state the step only has to point the right way; with no
    /// change at all, the settled forcing (see [`update`](Self::update)).
    pub(crate) fn rtol(&self, loading: bool, changes: usize, contact_nodes: usize) -> f64 {
        if loading {
            self.min
        } else if changes as f64 > 0.01 * contact_nodes as f64 {
            self.active_set.max(self.eta)
        } else if changes > 0 {
            self.eta
        } else {
            self.settled
        }
    }

    /// After an accepted step: `η = 0.9 (φ/φ_prev)²` (choice 2), but no tighter than
    /// `0.1 tol / err` (a correction of about `err`, the last one, solved to that relative
    /// residual errs by a tenth of the tolerance), within the bounds. The settled forcing
    /// sizes that term by the coming correction predicted from the last one, shrunk as the
    /// natural residual just shrank (`err φ/φ_prev`): with the active set standing still the
    /// corrections fall with the residual, and sizing the forcing by the last correction
    /// asks 10–100× more of the final linear solve than its result needs (the MNI152
    /// updates: 11 % fewer GMRES iterations, the answers within 6e-5 mm of before). While
    /// contact nodes still change state the residual's fall predicts nothing (at ν = 0.499
    /// the predicted sizing took the demo from 43 to 129 iterations), so `η` keeps the last
    /// correction.
    pub(crate) fn update(&mut self, phi: f64, phi_prev: f64, err: f64, tol: f64) {
        let ew = if phi_prev > 0.0 { 0.9 * (phi / phi_prev).powi(2) } else { self.max };
        let enough = |size: f64| if size > 0.0 { 0.1 * tol / size } else { 0.0 };
        let next = if phi_prev > 0.0 { err * (phi / phi_prev).min(1.0) } else { err };
        self.eta = ew.max(enough(err)).clamp(self.min, self.max);
        self.settled = ew.max(enough(next)).clamp(self.min, self.max);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_convergence_tightens_the_forcing_down_to_what_the_tolerance_needs() {
        let mut f = Forcing::new(1e-2, 0.1, 0.5);
        assert_eq!(f.rtol(false, 0, 100), 0.1);
        // The residual fell 10×: η = 0.9 · 0.01 = 0.009 → clamped to the minimum (the
        // next correction, about 1.0 · 0.1, needs only 0.1 · 1e-3 / 0.1 = 1e-3).
        f.update(1.0, 10.0, 1.0, 1e-3);
        assert_eq!(f.rtol(false, 0, 100), 1e-2);
        // Near the tolerance a loose solve is enough: the last correction 2e-2 with the
        // residual down 10× predicts 2e-3 next, for which 0.1 · 1e-3 / 2e-3 = 0.05 with the
        // active set standing still; sized by the last correction (nodes still changing
        // state) it is 0.005, clamped to 0.01.
        f.update(1.0, 10.0, 2e-2, 1e-3);
        assert!((f.rtol(false, 0, 100) - 0.05).abs() < 1e-15, "{}", f.rtol(false, 0, 100));
        assert_eq!(f.rtol(false, 1, 100), 1e-2);
        f.update(1.0, 10.0, 2e-3, 1e-3);
        // Loading asks for the minimum; a moving active set for at least 0.5.
        assert_eq!(f.rtol(true, 0, 100), 1e-2);
        assert_eq!(f.rtol(false, 2, 100), 0.5);
        assert!((f.rtol(false, 1, 100) - 0.05).abs() < 1e-15);
    }
}
