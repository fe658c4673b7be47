//! Robust statistics of residuals: the scale estimate and Tukey's biweight.
//!
//! A fit starts far from its data (the brain has not moved yet), so the first residuals
//! are the shift itself, not noise. The scale is therefore re-estimated at every
//! linearisation from the residuals (the median absolute residual times 1.4826, the
//! normal distribution's consistency factor), never below the measurement's `σ`; the
//! biweight's cut-off `c = 4.685 s` (95 % efficiency at the normal distribution) then
//! admits every point early on and closes on `4.685 σ` as the fit converges, where
//! outliers (specular highlights, blood, instruments) get weight zero. This is graduated
//! non-convexity without a schedule: the redescending loss acts only once the scale says
//! the fit is close.

/// Tukey's biweight tuning constant for 95 % efficiency at the normal distribution.
pub const TUKEY_C: f64 = 4.685;

/// The normal distribution's consistency factor of the median absolute deviation.
pub const MAD_TO_SIGMA: f64 = 1.4826;

/// The robust scale of `residuals` (any sign): `max(σ, 1.4826 · median |r|)`; `σ` for none.
/// `scratch` is reused (caller-owned, no allocation once it is large enough).
pub fn scale(residuals: impl Iterator<Item = f64>, sigma: f64, scratch: &mut Vec<f64>) -> f64 {
    scratch.clear();
    scratch.extend(residuals.map(f64::abs).filter(|r| r.is_finite()));
    if scratch.is_empty() {
        return sigma;
    }
    let mid = scratch.len() / 2;
    let (_, median, _) = scratch.select_nth_unstable_by(mid, f64::total_cmp);
    (MAD_TO_SIGMA * *median).max(sigma)
}

/// Tukey's biweight weight `(1 − (r/c)²)²` for `|r| < c`, else 0, with `c = 4.685 s`.
pub fn tukey(r: f64, s: f64) -> f64 {
    let c = TUKEY_C * s;
    if r.abs() >= c {
        return 0.0;
    }
    let t = r / c;
    let w = 1.0 - t * t;
    w * w
}

/// Whether a residual is inside the biweight's cut-off at scale `s` (its weight is not 0).
pub fn is_inlier(r: f64, s: f64) -> bool {
    r.abs() < TUKEY_C * s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// For standard normal residuals the scale comes out near 1 (the consistency factor),
    /// and a fifth of gross outliers moves it little (the median's breakdown is 50 %).
    #[test]
    fn the_scale_is_consistent_and_resists_outliers() {
        let mut rng = bs_mesh::rng::SplitMix64::new(7);
        let normal: Vec<f64> = (0..20_000).map(|_| rng.normal()).collect();
        let mut scratch = Vec::new();
        let s = scale(normal.iter().copied(), 0.01, &mut scratch);
        assert!((s - 1.0).abs() < 0.03, "{s}");
        let mut dirty = normal.clone();
        for r in dirty.iter_mut().step_by(5) {
            *r = 50.0;
        }
        let s = scale(dirty.iter().copied(), 0.01, &mut scratch);
        // A fifth of outliers moves the median to the normal's 62.5 % quantile of |r|
        // (0.887): 1.4826 · 0.887 = 1.31.
        assert!((s - 1.31).abs() < 0.05, "{s}");
        assert_eq!(scale(std::iter::empty(), 0.7, &mut scratch), 0.7);
        assert_eq!(scale([0.0, 0.0].into_iter(), 0.7, &mut scratch), 0.7);
    }

    #[test]
    fn the_biweight_is_one_at_zero_and_zero_beyond_the_cut_off() {
        assert_eq!(tukey(0.0, 1.0), 1.0);
        assert_eq!(tukey(4.685, 1.0), 0.0);
        assert_eq!(tukey(-10.0, 2.0), 0.0);
        // (1 − 0.25)² at half the cut-off.
        assert!((tukey(0.5 * 4.685 * 2.0, 2.0) - 0.5625).abs() < 1e-15);
        assert!(is_inlier(4.6, 1.0) && !is_inlier(4.7, 1.0));
    }
}
