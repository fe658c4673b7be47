//! How much σ a loose stop of the samples' solves leaves out, measured on the samples
//! themselves: GMRES stopped early misses part of each response's smooth component, so σ
//! comes out short (17 % on fixtures/fit-gravity at the relative residual 1e-2, 35 % at
//! 2e-2; docs/uncertainty.md). The first batch's responses are carried on to [`REFINED`]
//! from where they stopped, and the ratio of their energies after and before scales every
//! σ².

use bs_dr::nk::{NewtonKrylovError, Response};
use bs_mesh::Vector3;

/// The relative residual the first batch is refined to: σ within about 1 % of its
/// converged value on fixtures/fit and fixtures/fit-gravity.
pub const REFINED: f64 = 1e-3;

/// The factor on σ² for responses `dus` to `changes` solved to `rtol`: the energy of the
/// responses refined to [`REFINED`] over theirs as solved (1 when `rtol` is that tight
/// already or the responses are zero). `dus` is left refined.
pub(crate) fn scale(
    r: &mut Response<'_, '_>,
    changes: &[Vec<Vector3<f64>>],
    dus: &mut [Vec<Vector3<f64>>],
    rtol: f64,
) -> Result<f64, NewtonKrylovError> {
    if rtol <= REFINED {
        return Ok(1.0);
    }
    let before = energy(dus);
    r.refine_all(changes, dus, REFINED)?;
    let after = energy(dus);
    Ok(if before > 0.0 && after.is_finite() { after / before } else { 1.0 })
}

/// `Σ |δu|²` over the responses and nodes.
fn energy(dus: &[Vec<Vector3<f64>>]) -> f64 {
    dus.iter().flat_map(|d| d.iter()).map(|v| v.norm_squared()).sum()
}
