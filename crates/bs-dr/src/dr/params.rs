//! The parameters of Dynamic Relaxation and their ranges.

use crate::solver::{InvalidParam, ToleranceUnit, param};

/// Parameters of [`DynamicRelaxation`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrParams {
    /// Convergence tolerance on the error estimate, in [`DrParams::tolerance_unit`]. Default
    /// 1e-6.
    pub tolerance: f64,
    /// What the tolerance is measured in: a fraction of the load scale (the largest
    /// prescribed displacement component, or the bounding-box diagonal if none; the
    /// default) or a length.
    pub tolerance_unit: ToleranceUnit,
    /// Consecutive steps the error estimate must stay below the tolerance. Default 10.
    pub consecutive: usize,
    /// Step budget. Default 200 000.
    pub max_steps: usize,
    /// Steps of the 3-4-5 ramp of the prescribed displacements. Default 200.
    pub ramp_steps: usize,
    /// Time step as a fraction of the element critical step (< 1 is stable). Default 0.8.
    pub step_fraction: f64,
    /// Steps between Rayleigh-quotient snapshots. Default 100.
    pub snapshot_interval: usize,
    /// A fixed convergence rate ρ ∈ [0, 1) instead of the adaptive estimate. Default `None`.
    pub rho: Option<f64>,
    /// Divergence bound on `max|u|` as a multiple of the load scale. Default 100.
    pub divergence_factor: f64,
}

impl Default for DrParams {
    fn default() -> Self {
        DrParams {
            tolerance: 1e-6,
            tolerance_unit: ToleranceUnit::LoadScale,
            consecutive: 10,
            max_steps: 200_000,
            ramp_steps: 200,
            step_fraction: 0.8,
            snapshot_interval: 100,
            rho: None,
            divergence_factor: 100.0,
        }
    }
}

impl DrParams {
    /// Every parameter in its range, or the first one that is not.
    pub(crate) fn validate(&self) -> Result<(), InvalidParam> {
        let p = self;
        param("tolerance", p.tolerance, p.tolerance > 0.0, "must be > 0")?;
        param("consecutive", p.consecutive as f64, p.consecutive >= 1, "must be >= 1")?;
        param("max_steps", p.max_steps as f64, p.max_steps >= 1, "must be >= 1")?;
        param(
            "step_fraction",
            p.step_fraction,
            p.step_fraction > 0.0,
            "must be > 0 (< 1 is stable)",
        )?;
        param(
            "snapshot_interval",
            p.snapshot_interval as f64,
            p.snapshot_interval >= 2,
            "must be >= 2",
        )?;
        if let Some(r) = p.rho {
            param("rho", r, (0.0..1.0).contains(&r), "must lie in [0, 1)")?;
        }
        param("divergence_factor", p.divergence_factor, p.divergence_factor > 1.0, "must be > 1")?;
        Ok(())
    }
}
