//! The regularised, robustly weighted chord iteration for the basis amplitudes: weights,
//! the step of the normal equations, the discrepancy principle's `μ`, and the loop.
//!
//! The unknowns may end with a few load parameters beside the boundary's amplitudes (the
//! fluid's level, gravity's tilt: [`Priors`]). Those carry a Gaussian prior of their own,
//! `σ²/s_k² θ_k²` in the weighted misfit's units (`s_k` the prior's standard deviation,
//! `σ` the landmarks' noise), where the amplitudes carry the discrepancy principle's
//! `μ |a|²`; the step, the principle and the posterior covariance treat each column with
//! its own penalty.

use nalgebra::{DMatrix, DVector};

/// How the chord iteration stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChordParams {
    /// Chord steps at most.
    pub steps: usize,
    /// A step the model cannot carry is halved at most this often.
    pub halvings: usize,
    /// The inliers' RMS residual must fall by this factor per step to go on.
    pub progress: f64,
}

impl Default for ChordParams {
    fn default() -> Self {
        ChordParams { steps: 4, halvings: 4, progress: 0.97 }
    }
}

/// One model evaluation: the displacement at the landmarks (stacked) with the amplitudes'
/// field imposed, and what the caller keeps of the solve; an error when the model cannot
/// carry them.
pub type Evaluation<T, E> = Result<(DVector<f64>, T), E>;

/// The fit's answer: the amplitudes, the inliers' RMS residual per axis there, and what the
/// model's closure returned for them; `covariance` the unknowns' posterior covariance
/// `σ² (JᵀWJ + diag(penalty))⁻¹` at the answer's weights (the load parameters' block is
/// their standard errors; the amplitudes' is conditioned on `μ`).
#[derive(Debug, Clone, PartialEq)]
pub struct ChordFit<T> {
    pub amplitudes: DVector<f64>,
    pub rms: f64,
    pub answer: T,
    pub covariance: DMatrix<f64>,
}

/// The prior standard deviations of the trailing load parameters among the unknowns (empty:
/// the boundary's amplitudes alone), in the parameters' own units.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Priors<'a> {
    pub sd: &'a [f64],
}

impl Priors<'_> {
    /// Each column's penalty in the weighted misfit's units: `mu` for an amplitude,
    /// `σ²/s²` for a load parameter (the last `sd.len()` of `n` columns).
    pub fn penalty(&self, n: usize, mu: f64, sigma: f64) -> DVector<f64> {
        let first = n - self.sd.len().min(n);
        DVector::from_fn(
            n,
            |k, _| {
                if k < first { mu } else { (sigma / self.sd[k - first]).powi(2) }
            },
        )
    }
}

/// Robust weights of the stacked residuals `r` (3 per landmark; Tukey's biweight of
/// `|r_i|/√3` at the robust scale, ≥ `sigma`) per component, and the inliers' RMS residual
/// per axis.
pub fn weights(r: &DVector<f64>, sigma: f64) -> (DVector<f64>, f64) {
    let n = r.len() / 3;
    let axis = 3f64.sqrt();
    let norms: Vec<f64> = (0..n).map(|i| r.fixed_rows::<3>(3 * i).norm() / axis).collect();
    let s = crate::robust::scale(norms.iter().copied(), sigma, &mut Vec::new());
    let mut w = DVector::zeros(3 * n);
    let (mut sum, mut count) = (0.0, 0usize);
    for (i, &e) in norms.iter().enumerate() {
        let wi = crate::robust::tukey(e, s);
        if wi > 0.0 {
            sum += e * e;
            count += 1;
        }
        w.fixed_rows_mut::<3>(3 * i).fill(wi);
    }
    (w, (sum / count.max(1) as f64).sqrt())
}

/// The step `δa` of the regularised normal equations `(JᵀWJ + P) δa = JᵀW r − P a`,
/// `P = diag(penalty)` (`μ I` for amplitudes alone, [`Priors::penalty`]).
pub fn step(
    j: &DMatrix<f64>,
    w: &DVector<f64>,
    r: &DVector<f64>,
    a: &DVector<f64>,
    penalty: &DVector<f64>,
) -> DVector<f64> {
    let m = regularised(j, w, penalty);
    let jw = DMatrix::from_fn(j.nrows(), j.ncols(), |i, k| j[(i, k)] * w[i]);
    let rhs = jw.transpose() * r - a.component_mul(penalty);
    m.cholesky().map_or_else(|| DVector::zeros(a.len()), |c| c.solve(&rhs))
}

/// `JᵀWJ + diag(penalty)`.
fn regularised(j: &DMatrix<f64>, w: &DVector<f64>, penalty: &DVector<f64>) -> DMatrix<f64> {
    let jw = DMatrix::from_fn(j.nrows(), j.ncols(), |i, k| j[(i, k)] * w[i]);
    let mut m = jw.transpose() * j;
    for k in 0..m.nrows() {
        m[(k, k)] += penalty[k];
    }
    m
}

/// The unknowns' posterior covariance `σ² (JᵀWJ + diag(penalty))⁻¹` (zero when singular).
pub fn covariance(
    sigma: f64,
    j: &DMatrix<f64>,
    w: &DVector<f64>,
    penalty: &DVector<f64>,
) -> DMatrix<f64> {
    let n = j.ncols();
    regularised(j, w, penalty)
        .cholesky()
        .map_or_else(|| DMatrix::zeros(n, n), |c| c.inverse() * (sigma * sigma))
}

/// The discrepancy principle's `μ`, counting the degrees of freedom the fit uses: the
/// smallest `μ` whose predicted weighted residual reaches the noise left after fitting,
/// `Σ w r² = σ² (m − tr H_μ)` (`m` the weighted components, `H_μ` the influence matrix
/// `J (JᵀWJ + μI)⁻¹ JᵀW`), by bisection on `log μ` relative to the normal matrix's scale;
/// 0 when the least-squares step already leaves that much. The load parameters of
/// `priors` keep their own penalty throughout.
pub fn discrepancy(
    sigma: f64,
    j: &DMatrix<f64>,
    w: &DVector<f64>,
    r: &DVector<f64>,
    a: &DVector<f64>,
    priors: &Priors<'_>,
) -> f64 {
    let m: f64 = w.iter().sum::<f64>();
    let jw = DMatrix::from_fn(j.nrows(), j.ncols(), |i, k| j[(i, k)] * w[i]);
    let normal = jw.transpose() * j;
    // Positive when the fit at μ leaves more than the noise.
    let excess = |mu: f64| {
        let penalty = priors.penalty(j.ncols(), mu, sigma);
        let left = r - j * step(j, w, r, a, &penalty);
        let misfit: f64 = left.iter().zip(w.iter()).map(|(x, wi)| wi * x * x).sum();
        let trace =
            regularised(j, w, &penalty).cholesky().map_or(0.0, |c| (c.solve(&normal)).trace());
        misfit - sigma * sigma * (m - trace).max(0.0)
    };
    if excess(0.0) >= 0.0 {
        return 0.0;
    }
    let scale = normal.diagonal().max().max(f64::MIN_POSITIVE);
    let (mut lo, mut hi) = (-10.0f64, 6.0f64);
    if excess(scale * 10f64.powf(hi)) <= 0.0 {
        return scale * 10f64.powf(hi);
    }
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if excess(scale * 10f64.powf(mid)) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    scale * 10f64.powf(lo)
}

/// Chord steps from `a = 0` with the Jacobian `j` (`∂u(X_i)/∂a`, stacked) towards the
/// measured displacements `d` (stacked, noise `sigma`), `at_rest` the model's displacement
/// at the landmarks with the boundary at rest. `model(a)` solves the model with the field
/// of amplitudes `a` imposed and returns its displacement at the landmarks (stacked) and
/// what the caller keeps of the solve; an error means the model cannot carry `a`, and the
/// step is halved (at most `params.halvings` times). `μ` is set once, by [`discrepancy`]
/// at the start. Returns the answer of lowest inlier RMS, or the first step's error when
/// no step was carried. The last columns of `j` may be load parameters with `priors`.
pub fn chord_fit<T, E>(
    d: &DVector<f64>,
    sigma: f64,
    j: &DMatrix<f64>,
    at_rest: &DVector<f64>,
    priors: &Priors<'_>,
    params: &ChordParams,
    model: &mut dyn FnMut(&DVector<f64>) -> Evaluation<T, E>,
) -> Result<ChordFit<T>, E> {
    let mut a = DVector::zeros(j.ncols());
    let mut r = d - at_rest;
    let (mut w, _) = weights(&r, sigma);
    let mu = discrepancy(sigma, j, &w, &r, &a, priors);
    let penalty = priors.penalty(j.ncols(), mu, sigma);
    let mut best: Option<ChordFit<T>> = None;
    for _ in 0..params.steps {
        let mut delta = step(j, &w, &r, &a, &penalty);
        let mut halvings = 0;
        let attempt = loop {
            match model(&(&a + &delta)) {
                Ok(v) => break Some(v),
                Err(_) if halvings < params.halvings => {
                    delta *= 0.5;
                    halvings += 1;
                }
                Err(e) if best.is_none() => return Err(e),
                Err(_) => break None,
            }
        };
        let Some((u, answer)) = attempt else { break };
        a += delta;
        r = d - u;
        let (w_new, rms) = weights(&r, sigma);
        w = w_new;
        let previous = best.as_ref().map(|b| b.rms);
        if previous.is_none_or(|r0| rms < r0) {
            let covariance = covariance(sigma, j, &w, &penalty);
            best = Some(ChordFit { amplitudes: a.clone(), rms, answer, covariance });
        }
        if previous.is_some_and(|r0| rms > params.progress * r0) {
            break;
        }
    }
    Ok(best.expect("the loop carries a step or returns its error"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear model `u = u₀ + J a` with exact data: the chord steps recover the amplitudes,
    /// and the answer is the closure's. The discrepancy principle regularises until the
    /// residual is the noise (σ √(m − tr H) ≈ 3e-9 here), which bounds the amplitudes' error
    /// by about 1e-8 at this J's conditioning: 1e-6 is a safe tolerance.
    #[test]
    fn a_linear_model_is_fitted_to_its_amplitudes() {
        let j = DMatrix::from_fn(12, 2, |i, k| ((i + 1) * (k + 2)) as f64 * 0.1 + (i % 3) as f64);
        let at_rest = DVector::from_fn(12, |i, _| 0.01 * i as f64);
        let truth = DVector::from_vec(vec![0.7, -0.3]);
        let d = &at_rest + &j * &truth;
        let mut calls = 0;
        let fit = chord_fit(
            &d,
            1e-9,
            &j,
            &at_rest,
            &Priors::default(),
            &ChordParams::default(),
            &mut |a| {
                calls += 1;
                Ok::<_, ()>((&at_rest + &j * a, calls))
            },
        )
        .unwrap();
        assert!((&fit.amplitudes - &truth).norm() < 1e-6, "{}", fit.amplitudes);
        assert!(fit.rms < 1e-6);
        assert_eq!(fit.answer, 1, "the first step is exact and the best");
    }

    /// A model that cannot carry the full step takes the halved one; a model that carries
    /// nothing returns its error.
    #[test]
    fn steps_the_model_cannot_carry_are_halved() {
        let j = DMatrix::identity(6, 2);
        let zero = DVector::zeros(6);
        let d = DVector::from_vec(vec![2.0, 2.0, 0.0, 0.0, 0.0, 0.0]);
        let p = ChordParams { steps: 1, ..ChordParams::default() };
        let fit = chord_fit(&d, 1e-9, &j, &zero, &Priors::default(), &p, &mut |a| {
            if a.norm() > 1.5 { Err("inverts") } else { Ok((&j * a, a.norm())) }
        })
        .unwrap();
        // Step (2, 2) is too long; (1, 1) is carried (to the discrepancy's 1e-9).
        assert!((fit.answer - 2f64.sqrt()).abs() < 1e-6, "{}", fit.answer);
        let e = chord_fit(&d, 1e-9, &j, &zero, &Priors::default(), &p, &mut |_| {
            Err::<(DVector<f64>, ()), _>("no")
        });
        assert_eq!(e.unwrap_err(), "no");
    }

    /// A load parameter the data see is recovered with the least-squares standard error
    /// `σ/|j|` (its prior 100× wider), and one they do not see keeps its prior: zero, with
    /// the prior's standard deviation. The amplitude column is exact data (μ = 0).
    #[test]
    fn a_load_parameter_has_its_prior_where_the_data_are_silent() {
        let n = 30;
        let j = DMatrix::from_fn(n, 3, |i, k| match k {
            0 => 1.0 + (i % 3) as f64,
            1 => 0.5 * (i as f64 / n as f64 - 0.5),
            _ => 0.0,
        });
        let truth = DVector::from_vec(vec![0.2, 4.0, 0.0]);
        let sigma = 1e-3;
        // Noise of ±σ alternating, orthogonal to neither column: what is left is near σ.
        let noise = DVector::from_fn(n, |i, _| if (i / 3) % 2 == 0 { sigma } else { -sigma });
        let d = &j * &truth + &noise;
        let sd = [1.0, 2.0];
        let priors = Priors { sd: &sd };
        let p = ChordParams { steps: 1, ..ChordParams::default() };
        let zero = DVector::zeros(n);
        let fit = chord_fit(&d, sigma, &j, &zero, &priors, &p, &mut |a| Ok::<_, ()>((&j * a, ())))
            .unwrap();
        let seen = sigma / j.column(1).norm();
        assert!((fit.amplitudes[1] - 4.0).abs() < 4.0 * seen, "{}", fit.amplitudes);
        assert!((fit.covariance[(1, 1)].sqrt() / seen - 1.0).abs() < 0.05, "{}", fit.covariance);
        assert_eq!(fit.amplitudes[2], 0.0);
        assert!((fit.covariance[(2, 2)].sqrt() - 2.0).abs() < 1e-9, "{}", fit.covariance);
    }

    /// Tukey's weights drop a gross outlier and keep the rest at full weight.
    #[test]
    fn an_outlier_gets_no_weight() {
        let mut r = DVector::from_fn(30, |i, _| if i % 2 == 0 { 0.1 } else { -0.1 });
        r[0] = 50.0;
        let (w, rms) = weights(&r, 0.1);
        assert_eq!(w.fixed_rows::<3>(0).sum(), 0.0);
        assert!(w.rows(3, 27).iter().all(|&x| x > 0.5));
        assert!((rms - 0.1).abs() < 1e-12, "{rms}");
    }
}
