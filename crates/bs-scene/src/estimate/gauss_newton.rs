//! The few-parameter Gauss–Newton step with a Gaussian prior: residuals `r(θ)` (one per
//! measured point), their weights `w` (robust weight over the squared noise scale), the
//! Jacobian `J = ∂r/∂θ`, and prior standard deviations `σ_k` around `θ = 0`. The step
//! minimises `Σ w_i (r_i + J_i δ)² + Σ ((θ_k + δ_k)/σ_k)²`, and the inverse of its normal
//! matrix is the posterior covariance the standard errors come from.

use nalgebra::{DMatrix, DVector};

/// The weighted misfit plus the prior's penalty at `theta`.
pub(crate) fn objective(r: &DVector<f64>, w: &DVector<f64>, theta: &[f64], sd: &[f64]) -> f64 {
    let misfit: f64 = r.iter().zip(w.iter()).map(|(r, w)| w * r * r).sum();
    misfit + theta.iter().zip(sd).map(|(t, s)| (t / s).powi(2)).sum::<f64>()
}

/// The step `δ` and the posterior covariance `(JᵀWJ + P)⁻¹` at `theta`.
pub(crate) fn step(
    j: &DMatrix<f64>,
    r: &DVector<f64>,
    w: &DVector<f64>,
    theta: &[f64],
    sd: &[f64],
) -> (DVector<f64>, DMatrix<f64>) {
    let jw = DMatrix::from_fn(j.nrows(), j.ncols(), |i, k| j[(i, k)] * w[i]);
    let mut normal = jw.transpose() * j;
    let mut rhs = -(jw.transpose() * r);
    for k in 0..theta.len() {
        let p = 1.0 / (sd[k] * sd[k]);
        normal[(k, k)] += p;
        rhs[k] -= p * theta[k];
    }
    // The prior makes the normal matrix positive definite.
    let chol = normal.cholesky().expect("a positive prior makes JᵀWJ + P positive definite");
    (chol.solve(&rhs), chol.inverse())
}

/// Broyden's update of `j` along the step `s` that changed the residuals by `y` beyond
/// what `j` predicted (`y = Δr − J s`), in the prior's units: the least change of `J S`
/// (`S` the prior standard deviations) that makes `J s` equal `Δr`. Unscaled, a step of a
/// few hundredths of a radian beside one of a few hundredths of a millimetre puts the
/// whole change on the parameter whose unit is smallest.
pub(crate) fn broyden(j: &mut DMatrix<f64>, y: &DVector<f64>, s: &DVector<f64>, sd: &[f64]) {
    let scaled = DVector::from_iterator(s.len(), s.iter().zip(sd).map(|(s, d)| s / (d * d)));
    let norm = s.dot(&scaled);
    if norm > 0.0 {
        *j += y * scaled.transpose() / norm;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The update meets the secant condition, and it does not depend on the parameters'
    /// units: a parameter measured in units a thousand times smaller (its prior too) gets
    /// the same column, a thousand times larger.
    #[test]
    fn broydens_update_meets_the_secant_condition_whatever_the_units() {
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 0.5, -1.0, 0.0, 3.0]);
        let truth = DMatrix::from_row_slice(3, 2, &[1.5, 2.0, 0.2, -0.5, 1.0, 2.0]);
        let s = DVector::from_vec(vec![0.3, -0.2]);
        let y = &truth * &s - &j * &s;
        let mut a = j.clone();
        broyden(&mut a, &y, &s, &[1.0, 1.0]);
        assert!((&a * &s - &truth * &s).norm() < 1e-12);
        // The second parameter in units 1000× smaller: θ₂' = θ₂ / 1000, σ₂' = σ₂ / 1000.
        let c = 1000.0;
        let mut b = j.clone();
        b.column_mut(1).scale_mut(c);
        let s2 = DVector::from_vec(vec![0.3, -0.2 / c]);
        broyden(&mut b, &y, &s2, &[1.0, 1.0 / c]);
        assert!((b.column(0) - a.column(0)).norm() < 1e-9, "{b} {a}");
        assert!((b.column(1) / c - a.column(1)).norm() < 1e-9, "{b} {a}");
        // Unscaled (equal priors) the small unit's column would take almost none of it.
        let mut u = j.clone();
        u.column_mut(1).scale_mut(c);
        broyden(&mut u, &y, &s2, &[1.0, 1.0]);
        assert!((u.column(0) - a.column(0)).norm() > 0.1);
    }

    /// On a linear model one step from anywhere lands on the closed-form minimiser, and the
    /// covariance is the inverse normal matrix; with a vanishing prior, least squares.
    #[test]
    fn one_step_solves_a_linear_problem_and_its_covariance_is_the_inverse_normal_matrix() {
        let a = DMatrix::from_row_slice(4, 2, &[1.0, 0.0, 0.0, 2.0, 1.0, 1.0, 3.0, -1.0]);
        let truth = DVector::from_vec(vec![0.7, -0.4]);
        let d = &a * &truth;
        let w = DVector::from_vec(vec![1.0, 4.0, 0.5, 2.0]);
        // r(θ) = A θ − d.
        let theta = [5.0, 5.0];
        let r = &a * DVector::from_row_slice(&theta) - &d;
        let (delta, cov) = step(&a, &r, &w, &theta, &[1e6, 1e6]);
        let found = DVector::from_row_slice(&theta) + delta;
        assert!((found - &truth).norm() < 1e-9);
        let wa = DMatrix::from_fn(4, 2, |i, k| a[(i, k)] * w[i]);
        let expected = (a.transpose() * wa).try_inverse().unwrap();
        assert!((cov - expected).norm() < 1e-9);
        // A tight prior holds θ at zero; the objective then counts only the misfit.
        let (delta, _) = step(&a, &r, &w, &theta, &[1e-6, 1e-6]);
        let held = DVector::from_row_slice(&theta) + delta;
        assert!(held.norm() < 1e-6, "{held}");
        let at_truth = &a * &truth - &d;
        assert!(objective(&at_truth, &w, &[0.0, 0.0], &[1.0, 1.0]).abs() < 1e-20);
        assert!((objective(&at_truth, &w, &[2.0, 0.0], &[1.0, 1.0]) - 4.0).abs() < 1e-12);
    }
}
