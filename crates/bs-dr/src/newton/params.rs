//! The parameters of the Newton–Raphson reference and their ranges.

use crate::solver::{InvalidParam, ToleranceUnit, param};

/// Parameters of [`Newton`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonParams {
    /// Number of equal load steps. Default 10.
    pub load_steps: usize,
    /// Convergence tolerance on `max|δu|`, in [`NewtonParams::tolerance_unit`]. Default 1e-10.
    pub tolerance: f64,
    /// What the tolerance is measured in (default: a fraction of the load scale).
    pub tolerance_unit: ToleranceUnit,
    /// Iterations allowed per load step. Default 30.
    pub max_iterations: usize,
    /// Backtracking line search on the residual norm. Default true.
    pub line_search: bool,
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams {
            load_steps: 10,
            tolerance: 1e-10,
            tolerance_unit: ToleranceUnit::LoadScale,
            max_iterations: 30,
            line_search: true,
        }
    }
}

impl NewtonParams {
    /// Every parameter in its range, or the first one that is not.
    pub(crate) fn validate(&self) -> Result<(), InvalidParam> {
        param("load_steps", self.load_steps as f64, self.load_steps >= 1, "must be >= 1")?;
        param("tolerance", self.tolerance, self.tolerance > 0.0, "must be > 0")?;
        let its = self.max_iterations;
        param("max_iterations", its as f64, its >= 1, "must be >= 1")
    }
}
