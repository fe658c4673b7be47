//! The Rayleigh estimator of Dynamic Relaxation's convergence rate: snapshots of `u` and `f`
//! every `snapshot_interval` steps after the ramp give `ω²_min ≈ |Δuᵀ Δf| / (Δuᵀ M Δu)` over
//! the free DOFs (the Rayleigh quotient of `M⁻¹K` along the slowest mode, which dominates
//! `Δu` once the fast ones are damped); an estimate is accepted when the next one agrees
//! within 10%, and sets `ρ = (κ − 1)/(κ + 1)`, `κ = 2/(ω_min h)`. The decay rate of `max|Δu|`
//! over each window is kept for the error estimate.

/// `ρ = (κ − 1)/(κ + 1)` with `κ = 2/(ω h)`, `h = 1`.
pub(crate) fn rho_of(omega: f64) -> f64 {
    let w = omega.clamp(1e-12, 2.0);
    (2.0 - w) / (2.0 + w)
}

/// The estimator's state between snapshots.
#[derive(Debug, Clone)]
pub(crate) struct RayleighEstimator {
    /// Steps of the ramp (no snapshot before it ends).
    ramp_steps: usize,
    /// Steps between snapshots.
    interval: usize,
    /// A fixed ρ given by the caller (the estimate then only feeds the error estimate).
    fixed: bool,
    omega: f64,
    rho: f64,
    last_estimate: Option<f64>,
    snap_u: Vec<bs_mesh::Vector3<f64>>,
    snap_f: Vec<bs_mesh::Vector3<f64>>,
    have_snapshot: bool,
    snap_maxd: f64,
    /// Observed decay rate of `max|Δu|` per step over the last window.
    rate: Option<f64>,
}

impl RayleighEstimator {
    /// An estimator for `n` nodes starting from `omega_guess`, or with the fixed rate `rho`.
    pub(crate) fn new(
        n: usize,
        omega_guess: f64,
        rho: Option<f64>,
        ramp_steps: usize,
        interval: usize,
    ) -> Self {
        let zero = vec![bs_mesh::Vector3::zeros(); n];
        RayleighEstimator {
            ramp_steps,
            interval,
            fixed: rho.is_some(),
            omega: omega_guess,
            rho: rho.unwrap_or_else(|| rho_of(omega_guess)),
            last_estimate: None,
            snap_u: zero.clone(),
            snap_f: zero,
            have_snapshot: false,
            snap_maxd: 0.0,
            rate: None,
        }
    }

    /// The convergence rate in use.
    pub(crate) fn rho(&self) -> f64 {
        self.rho
    }

    /// The lowest-eigenvalue estimate in use (units of 1/h).
    pub(crate) fn omega(&self) -> f64 {
        self.omega
    }

    /// At the state after `k` steps, with forces `f`, nodal `masses` and `max|Δu|` = `maxd`
    /// of the step that led to it: takes a snapshot if one is due, and with the previous one
    /// an estimate (accepted if it agrees with the last one) and the observed rate.
    pub(crate) fn observe(
        &mut self,
        k: usize,
        u: &[bs_mesh::Vector3<f64>],
        f: &[bs_mesh::Vector3<f64>],
        masses: &[f64],
        free: &[usize],
        maxd: f64,
    ) {
        if k < self.ramp_steps || !(k - self.ramp_steps).is_multiple_of(self.interval) {
            return;
        }
        if self.have_snapshot {
            self.estimate(u, f, masses, free);
            self.rate = Some(if self.snap_maxd > 0.0 {
                (maxd / self.snap_maxd).powf(1.0 / self.interval as f64)
            } else {
                0.0
            });
        }
        self.snap_u.copy_from_slice(u);
        self.snap_f.copy_from_slice(f);
        self.snap_maxd = maxd;
        self.have_snapshot = true;
    }

    /// The Rayleigh quotient between the last snapshot and now.
    fn estimate(
        &mut self,
        u: &[bs_mesh::Vector3<f64>],
        f: &[bs_mesh::Vector3<f64>],
        masses: &[f64],
        free: &[usize],
    ) {
        let (mut num, mut den) = (0.0, 0.0);
        for &d in free {
            let (a, c) = (d / 3, d % 3);
            let du = u[a][c] - self.snap_u[a][c];
            num += du * (f[a][c] - self.snap_f[a][c]);
            den += masses[a] * du * du;
        }
        if den > 0.0 && num.is_finite() {
            let est = (num.abs() / den).sqrt();
            if !self.fixed
                && let Some(prev) = self.last_estimate
                && (est - prev).abs() <= 0.1 * est
            {
                self.omega = est;
                self.rho = rho_of(est);
            }
            self.last_estimate = Some(est);
        }
    }

    /// The error estimate after `step` steps whose last change was `max|Δu|` = `maxd`:
    /// `maxd ρₑ/(1 − ρₑ)`, `ρₑ` the most pessimistic of `ρ(0.9 ω)`, `ρ` and the observed
    /// rate; infinite until a rate has been observed after the ramp.
    pub(crate) fn error_estimate(&self, step: usize, maxd: f64) -> f64 {
        match self.rate {
            Some(r) if step >= self.ramp_steps => {
                let rho_e = rho_of(0.9 * self.omega).max(self.rho).max(r);
                if rho_e < 1.0 { maxd * rho_e / (1.0 - rho_e) } else { f64::INFINITY }
            }
            _ => f64::INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use bs_mesh::Vector3;

    use super::*;

    /// `u` along one mode of `K = k I` (unit masses), `f = K u`: the quotient is `√k`.
    fn mode(scale: f64, k: f64) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
        let u: Vec<_> = (0..4).map(|a| Vector3::new(1.0, -0.5, a as f64) * scale).collect();
        let f = u.iter().map(|v| v * k).collect();
        (u, f)
    }

    #[test]
    fn rho_is_the_closed_form_and_clamped() {
        assert!((rho_of(0.1) - 1.9 / 2.1).abs() < 1e-15);
        assert_eq!(rho_of(5.0), 0.0);
        assert!(rho_of(0.0) < 1.0 && rho_of(0.0) > 1.0 - 1e-11);
    }

    #[test]
    fn an_estimate_is_accepted_when_the_next_one_agrees() {
        let (free, masses) = ((0..12).collect::<Vec<_>>(), vec![1.0; 4]);
        let mut r = RayleighEstimator::new(4, 0.5, None, 10, 5);
        let (k, guess) = (0.04, rho_of(0.5));
        // Before the ramp ends and between snapshots nothing happens.
        let (u, f) = mode(1.0, k);
        r.observe(3, &u, &f, &masses, &free, 1.0);
        r.observe(10, &u, &f, &masses, &free, 1.0);
        r.observe(12, &u, &f, &masses, &free, 1.0);
        assert_eq!((r.rho(), r.error_estimate(12, 1.0)), (guess, f64::INFINITY));
        // The first quotient (√k = 0.2) is only remembered; the rate is observed.
        let (u, f) = mode(2.0, k);
        r.observe(15, &u, &f, &masses, &free, 0.5);
        assert_eq!((r.rho(), r.omega()), (guess, 0.5));
        let rate = 0.5f64.powf(1.0 / 5.0);
        let rho_e = rho_of(0.9 * 0.5).max(guess).max(rate);
        assert!((r.error_estimate(15, 0.1) - 0.1 * rho_e / (1.0 - rho_e)).abs() < 1e-15);
        // The second agrees: accepted.
        let (u, f) = mode(3.5, k);
        r.observe(20, &u, &f, &masses, &free, 0.25);
        assert!((r.omega() - 0.2).abs() < 1e-12, "{}", r.omega());
        assert!((r.rho() - rho_of(0.2)).abs() < 1e-12);
    }

    #[test]
    fn a_fixed_rate_is_kept() {
        let (free, masses) = ((0..12).collect::<Vec<_>>(), vec![1.0; 4]);
        let mut r = RayleighEstimator::new(4, 0.5, Some(0.9), 0, 2);
        for (step, scale) in [(0, 1.0), (2, 2.0), (4, 3.0)] {
            let (u, f) = mode(scale, 0.04);
            r.observe(step, &u, &f, &masses, &free, 1.0);
        }
        assert_eq!((r.rho(), r.omega()), (0.9, 0.5));
    }
}
