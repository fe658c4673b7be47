//! Gravity's unknowns estimated from the scan (`[gravity] estimate`).
//!
//! The operating room knows gravity's direction (from the tracked head pose, to a few
//! degrees); it does not know where the drained fluid stands or the tissue's effective
//! weight against its stiffness. With `estimate`, the few named parameters `θ` (the level's
//! shift along gravity, two tilts of the direction, the weight's factor) are fitted to the
//! scan, and to landmark pairs beside it, with the exact nonlinear model before the scan
//! pulls it:
//!
//! 1. the forward solve at `θ` (gravity only, no data term) deforms the brain; each scan
//!    point's signed distance from the exposed surface, and each landmark's miss (three
//!    components), is a residual ([`residuals`]) with its robust weight over the squared
//!    noise scale. A window scan sees the surface under it; landmarks deep in the brain see
//!    it sink as a whole;
//! 2. Gauss–Newton on `θ` with a Gaussian prior around the scene's values
//!    ([`gauss_newton`]): the sensitivities are forward differences, one forward solve per
//!    parameter warm from the current answer (a small load change: a few Newton
//!    iterations); the step is halved until the objective falls;
//! 3. the scan then pulls the model at the estimated gravity, warm from its forward answer
//!    (the measurement fit of docs/fit.md). Landmarks alone (no scan, no set) only measure:
//!    the answer is the model at the estimate.
//!
//! The posterior covariance `(JᵀWJ + P)⁻¹` gives each estimate's standard error; it
//! treats the points as independent, so it is a lower bound where the model's own error
//! is correlated over the window. A parameter the data do not determine keeps a standard
//! error near its prior's, and the report says so. When the data cannot be carried (the
//! data's pull inverts an element, the level leaves the brain) the answer is the prior's at
//! the last good `θ` and the report says why.

mod gauss_newton;
mod params;
mod residuals;

use bs_dr::{Progress, Solution, WarmStart};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::SceneError;
use crate::compose::{Composed, dead_loads, loads_of};
use crate::measure::FitState;
use crate::prepare::Prepared;
use crate::scene::Gravity;
use crate::solve::{SolveSettings, solve_composed_from};
use params::Param;
pub(crate) use params::Unknowns;
use residuals::{Residuals, residuals};

/// Gauss–Newton iterations at most.
pub const MAX_ITERATIONS: usize = 4;
/// A step is halved at most this often.
const MAX_HALVINGS: usize = 3;
/// Converged when every step is below this fraction of its standard error.
const STEP_OF_ERROR: f64 = 0.25;
/// A parameter is determined by the data when its standard error is below this fraction
/// of its prior's.
const DETERMINED: f64 = 0.5;

/// report.json's `gravity`: the gravity the answer was solved with, and what was estimated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GravityReport {
    /// Unit direction (scene frame).
    pub direction: [f64; 3],
    /// Acceleration (m/s²) times the estimated weight factor.
    pub acceleration: f64,
    /// A point of the fluid's level (scene frame and units), when there is a fluid.
    pub fluid_level: Option<[f64; 3]>,
    /// Each estimated parameter (empty without `estimate`).
    pub estimates: Vec<ParameterEstimate>,
    /// Gauss–Newton iterations and forward solves of the estimate.
    pub iterations: usize,
    pub solves: usize,
    /// Scan points with evidence at the estimate (inliers on the forward answer).
    pub inliers: usize,
    /// Landmarks with evidence at the estimate (inliers; 0 without landmarks).
    #[serde(default)]
    pub landmark_inliers: usize,
    /// Whether measurements pulled the answer (with an estimate: false when the data's pull
    /// could not be carried and the answer is the prior's at the estimate).
    pub data_used: bool,
    /// Why the estimate stopped early or the data could not be used (absent: neither).
    pub note: Option<String>,
    /// The estimate in its own coordinates (level shift, two tilts in radians, weight
    /// factor: those named) and their posterior covariance, row by row: what an
    /// uncertainty's samples draw from ([`body_at`]). Not written to report.json.
    #[serde(skip)]
    pub theta: Vec<f64>,
    #[serde(skip)]
    pub covariance: Vec<Vec<f64>>,
}

/// One estimated parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterEstimate {
    /// `level`, `direction` or `weight`.
    pub name: String,
    /// The estimate's offset from the scene's value: the level's shift along gravity (mesh
    /// units, positive deeper), the angle off the scene's direction (degrees), the weight's
    /// relative change.
    pub estimate: f64,
    /// Its standard error (same unit), and the prior's standard deviation.
    pub standard_error: f64,
    pub prior: f64,
    /// Whether the data determine it (standard error below half the prior's).
    pub determined: bool,
}

impl GravityReport {
    /// The report of a scene's own gravity, nothing estimated.
    pub fn of(g: &Gravity) -> GravityReport {
        GravityReport {
            direction: g.unit().unwrap_or(g.direction),
            acceleration: g.acceleration,
            fluid_level: g.fluid.map(|f| f.level),
            estimates: Vec::new(),
            iterations: 0,
            solves: 0,
            inliers: 0,
            landmark_inliers: 0,
            data_used: false,
            note: None,
            theta: Vec::new(),
            covariance: Vec::new(),
        }
    }

    /// The run line's words for the estimates (`level 9.60 ± 0.40 mm, weight 12.00 ± 5.00 %`).
    pub fn summary(&self, unit: &str) -> String {
        self.estimates
            .iter()
            .map(|e| {
                let u = match e.name.as_str() {
                    "level" => format!(" {unit}"),
                    "direction" => "°".into(),
                    _ => String::new(),
                };
                let flag = if e.determined { "" } else { " (not determined by the data)" };
                let v = if e.name == "weight" { 100.0 * e.estimate } else { e.estimate };
                let s =
                    if e.name == "weight" { 100.0 * e.standard_error } else { e.standard_error };
                let pct = if e.name == "weight" { " %" } else { "" };
                format!("{} {v:.2} ± {s:.2}{pct}{u}{flag}", e.name)
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Whether `p` estimates gravity.
pub fn estimates(p: &Prepared) -> bool {
    p.scene.gravity.as_ref().is_some_and(|g| g.estimate.is_some())
}

/// The estimate's state between iterations.
struct Estimated {
    theta: Vec<f64>,
    cov: DMatrix<f64>,
    prior: Solution,
    penetration: f64,
    res: Residuals,
    iterations: usize,
    solves: usize,
    note: Option<String>,
}

/// Estimates gravity's unknowns and fits the data at the estimate (module documentation):
/// the answer, its largest penetration, and report.json's `gravity`.
pub fn solve(
    p: &Prepared,
    c: &mut Composed,
    settings: &SolveSettings,
    observer: &mut dyn FnMut(&Progress),
) -> Result<(Solution, f64, GravityReport), SceneError> {
    let gravity = p.scene.gravity.clone().expect("estimates(p)");
    let unknowns = Unknowns::new(&gravity, &gravity.estimate.expect("estimates(p)"));
    let mut fit = c.fit.take().expect("an estimate has data (check_estimate_data)");
    let estimated = estimate(p, c, settings, &unknowns, &mut fit.fits, observer);
    c.fit = Some(fit);
    let mut e = estimated?;
    let at = unknowns.gravity_at(&e.theta);
    set_gravity(p, c, &at)?;
    let warm = WarmStart { state: &e.prior.displacements, secant: None };
    let (solution, penetration, data_used) =
        match solve_composed_from(c, settings, Some(warm), observer) {
            Ok((s, pen)) => (s, pen.max(e.penetration), true),
            Err(err) => {
                e.note = Some(format!(
                    "{} at the estimated gravity; the answer is the prior's there, without the \
                     data",
                    crate::measure::failure::pull_failure(p, &err)
                ));
                (e.prior.clone(), e.penetration, false)
            }
        };
    let report = report(&unknowns, &at, &e, data_used);
    Ok((solution, penetration, report))
}

/// Why an estimate's answer is the prior's, when `g` says the data were not used.
pub(crate) fn unused_reason(g: Option<&GravityReport>) -> Option<String> {
    g.filter(|g| !g.data_used)
        .map(|g| g.note.clone().unwrap_or_else(|| "the data were not used at the estimate".into()))
}

/// The data terms of `c` when the answer is the prior's (`unused`: the data were not used,
/// by an estimate or a fit that fell back): that answer is verified and reported without
/// them; the caller puts them back with [`restore`] for the next solve.
pub(crate) fn unused_data(c: &mut Composed, unused: bool) -> Option<FitState> {
    if unused { c.fit.take() } else { None }
}

/// Puts back what [`unused_data`] took.
pub(crate) fn restore(c: &mut Composed, kept: Option<FitState>) {
    if kept.is_some() {
        c.fit = kept;
    }
}

/// Gauss–Newton on the unknowns (module documentation); `fits` are the scans, kept out of
/// the composition so the forward solves are the prior alone.
fn estimate(
    p: &Prepared,
    c: &mut Composed,
    settings: &SolveSettings,
    unknowns: &Unknowns,
    fits: &mut bs_fit::Fits,
    observer: &mut dyn FnMut(&Progress),
) -> Result<Estimated, SceneError> {
    let n = unknowns.params.len();
    let sd = &unknowns.prior_sd;
    let (prior, penetration) = forward(p, c, settings, unknowns, &vec![0.0; n], None, observer)?;
    let res = residuals(fits, c.model.reference(), &prior.displacements);
    let cov = DMatrix::from_diagonal(&DVector::from_iterator(n, sd.iter().map(|s| s * s)));
    let mut e = Estimated {
        theta: vec![0.0; n],
        cov,
        prior,
        penetration,
        res,
        iterations: 0,
        solves: 1,
        note: None,
    };
    let probes = unknowns.probes(1e-3 / p.scene.units.metres());
    let Some((mut j, mut valid)) =
        jacobian(p, c, settings, unknowns, fits, &probes, &mut e, observer)
    else {
        return Ok(e);
    };
    // The weights at the current answer (its robust scale), where the Jacobian is known.
    let weights = |e: &Estimated, valid: &DVector<f64>| e.res.w.component_mul(valid);
    for _ in 0..MAX_ITERATIONS {
        e.iterations += 1;
        let w = weights(&e, &valid);
        let (delta, cov) = gauss_newton::step(&j, &e.res.r, &w, &e.theta, sd);
        e.cov = cov;
        let small = (0..n).all(|k| delta[k].abs() <= STEP_OF_ERROR * e.cov[(k, k)].sqrt());
        let (theta, r) = (e.theta.clone(), e.res.r.clone());
        if !line_search(p, c, settings, unknowns, fits, &delta, &w, &mut e, observer) || small {
            break;
        }
        // Broyden's update of the Jacobian along the step taken (the load's effect on the
        // surface is smooth; fresh probes would cost a solve per parameter).
        let step = DVector::from_iterator(n, e.theta.iter().zip(&theta).map(|(a, b)| a - b));
        for (v, &m) in valid.iter_mut().zip(&e.res.matched) {
            if !m {
                *v = 0.0;
            }
        }
        let change = &e.res.r - &r - &j * &step;
        gauss_newton::broyden(&mut j, &change, &step, sd);
    }
    // The covariance at the answer, with its weights.
    e.cov = gauss_newton::step(&j, &e.res.r, &weights(&e, &valid), &e.theta, sd).1;
    Ok(e)
}

/// The forward-difference Jacobian at `e.theta` and which points (1 or 0) were matched in
/// every probe; `None` (with the note) when a probe cannot be solved.
#[allow(clippy::too_many_arguments)]
fn jacobian(
    p: &Prepared,
    c: &mut Composed,
    settings: &SolveSettings,
    unknowns: &Unknowns,
    fits: &mut bs_fit::Fits,
    probes: &[f64],
    e: &mut Estimated,
    observer: &mut dyn FnMut(&Progress),
) -> Option<(DMatrix<f64>, DVector<f64>)> {
    let (m, n) = (e.res.r.len(), probes.len());
    let mut j = DMatrix::zeros(m, n);
    let mut valid = DVector::from_element(m, 1.0);
    for k in 0..n {
        let mut t = e.theta.clone();
        t[k] += probes[k];
        let warm = Some(e.prior.displacements.as_slice());
        e.solves += 1;
        let s = match forward(p, c, settings, unknowns, &t, warm, observer) {
            Ok((s, _)) => s,
            Err(err) => {
                e.note = Some(format!(
                    "the sensitivity to {} could not be solved: {err}",
                    name(unknowns.params[k])
                ));
                return None;
            }
        };
        let rk = residuals(fits, c.model.reference(), &s.displacements);
        for i in 0..m {
            if rk.matched[i] && e.res.matched[i] {
                j[(i, k)] = (rk.r[i] - e.res.r[i]) / probes[k];
            } else {
                valid[i] = 0.0;
            }
        }
    }
    Some((j, valid))
}

/// Steps `e.theta` by `delta`, halved until the objective (with weights `w`) falls; false
/// when no step does (the note says why).
#[allow(clippy::too_many_arguments)]
fn line_search(
    p: &Prepared,
    c: &mut Composed,
    settings: &SolveSettings,
    unknowns: &Unknowns,
    fits: &mut bs_fit::Fits,
    delta: &DVector<f64>,
    w: &DVector<f64>,
    e: &mut Estimated,
    observer: &mut dyn FnMut(&Progress),
) -> bool {
    let sd = &unknowns.prior_sd;
    let mut lambda = 1.0;
    let mut failure = None;
    for _ in 0..=MAX_HALVINGS {
        let t: Vec<f64> = e.theta.iter().zip(delta.iter()).map(|(t, d)| t + lambda * d).collect();
        let warm = Some(e.prior.displacements.as_slice());
        e.solves += 1;
        match forward(p, c, settings, unknowns, &t, warm, observer) {
            Ok((s, pen)) => {
                let r = residuals(fits, c.model.reference(), &s.displacements);
                let both = w.zip_map(
                    &DVector::from_iterator(
                        w.len(),
                        r.matched.iter().map(|&m| if m { 1.0 } else { 0.0 }),
                    ),
                    |a, b| a * b,
                );
                let before = gauss_newton::objective(&e.res.r, &both, &e.theta, sd);
                let after = gauss_newton::objective(&r.r, &both, &t, sd);
                if after < before {
                    (e.theta, e.prior, e.penetration, e.res) = (t, s, pen, r);
                    return true;
                }
            }
            Err(err) => failure = Some(format!("{}: {err}", describe(unknowns, &t))),
        }
        lambda *= 0.5;
    }
    // A step within its standard error that lowers nothing: converged, as far as the data
    // tell.
    let within = (0..delta.len()).all(|k| delta[k].abs() <= e.cov[(k, k)].sqrt());
    e.note = match failure {
        Some(f) => Some(format!("the estimate stopped where the model could not be solved at {f}")),
        None if within => None,
        None => Some(
            "the estimate stopped: no step along the Gauss–Newton direction lowered the misfit"
                .into(),
        ),
    };
    false
}

/// The forward solve (gravity only) at `theta`, warm from `warm` when given.
fn forward(
    p: &Prepared,
    c: &mut Composed,
    settings: &SolveSettings,
    unknowns: &Unknowns,
    theta: &[f64],
    warm: Option<&[bs_mesh::Vector3<f64>]>,
    observer: &mut dyn FnMut(&Progress),
) -> Result<(Solution, f64), SceneError> {
    gravity_for(p, c, unknowns, theta)?;
    let start = warm.map(|s| WarmStart { state: s, secant: None });
    solve_composed_from(c, settings, start, observer)
        .map_err(|e| crate::imposed::explain(p.imposed(), e))
}

/// Makes gravity at `theta` the composition's; a level that leaves the brain is named
/// with the estimate that put it there.
pub(crate) fn gravity_for(
    p: &Prepared,
    c: &mut Composed,
    unknowns: &Unknowns,
    theta: &[f64],
) -> Result<(), SceneError> {
    let g = unknowns.gravity_at(theta);
    set_gravity(p, c, &g).map_err(|err| match err {
        SceneError::Scene { file, message } if theta.iter().any(|&t| t != 0.0) => {
            SceneError::Scene {
                file,
                message: format!(
                    "the level estimate left the brain ({}): {message}",
                    describe(unknowns, theta)
                ),
            }
        }
        other => other,
    })
}

/// Makes `g` the composition's gravity.
fn set_gravity(p: &Prepared, c: &mut Composed, g: &Gravity) -> Result<(), SceneError> {
    let body = dead_loads(p, &c.model, Some(g))?;
    c.loads = loads_of(p, &p.prescribed, &body)?;
    c.body = body;
    Ok(())
}

fn name(p: Param) -> &'static str {
    match p {
        Param::Level => "the level",
        Param::TiltA | Param::TiltB => "the direction",
        Param::Weight => "the weight",
    }
}

/// `θ` in words: level shift, tilt, weight.
fn describe(u: &Unknowns, theta: &[f64]) -> String {
    let mut parts = Vec::new();
    for (p, t) in u.params.iter().zip(theta) {
        match p {
            Param::Level => parts.push(format!("level {t:+.1} along gravity")),
            Param::Weight => parts.push(format!("weight {:+.0} %", 100.0 * t)),
            _ => {}
        }
    }
    if u.params.contains(&Param::TiltA) {
        parts.push(format!("direction {:.1}° off", u.tilt(theta).to_degrees()));
    }
    parts.join(", ")
}

/// report.json's `gravity` of the estimate `e` at gravity `at`.
fn report(u: &Unknowns, at: &Gravity, e: &Estimated, data_used: bool) -> GravityReport {
    GravityReport {
        iterations: e.iterations,
        solves: e.solves + 1,
        inliers: e.res.inliers(),
        landmark_inliers: e.res.landmark_inliers(),
        data_used,
        note: e.note.clone(),
        ..estimated(u, at, &e.theta, &e.cov)
    }
}

/// report.json's `gravity` at `at` of the estimate `theta` with posterior covariance `cov`
/// (its counts zero and no note: the caller's to fill).
pub(crate) fn estimated(
    u: &Unknowns,
    at: &Gravity,
    theta: &[f64],
    cov: &DMatrix<f64>,
) -> GravityReport {
    GravityReport {
        estimates: parameter_estimates(u, theta, cov),
        data_used: true,
        theta: theta.to_vec(),
        covariance: (0..cov.nrows()).map(|i| cov.row(i).iter().copied().collect()).collect(),
        ..GravityReport::of(at)
    }
}

/// Each named parameter's estimate, standard error and prior (the two tilts as one angle).
fn parameter_estimates(u: &Unknowns, theta: &[f64], cov: &DMatrix<f64>) -> Vec<ParameterEstimate> {
    let mut estimates = Vec::new();
    let sd = |k: usize| cov[(k, k)].max(0.0).sqrt();
    let mut k = 0;
    while k < u.params.len() {
        let (estimate, error, prior, width) = match u.params[k] {
            Param::Level | Param::Weight => (theta[k], sd(k), u.prior_sd[k], 1),
            Param::TiltA | Param::TiltB => {
                // The angle off the scene's direction; its error the RMS of the two tilts'.
                let err = (0.5 * (sd(k).powi(2) + sd(k + 1).powi(2))).sqrt();
                (u.tilt(theta).to_degrees(), err.to_degrees(), u.prior_sd[k].to_degrees(), 2)
            }
        };
        let name = match u.params[k] {
            Param::Level => "level",
            Param::Weight => "weight",
            _ => "direction",
        };
        estimates.push(ParameterEstimate {
            name: name.into(),
            estimate,
            standard_error: error,
            prior,
            determined: error < DETERMINED * prior,
        });
        k += width;
    }
    estimates
}

/// The nodal dead loads of `p`'s gravity at the estimate of `g` moved by `offset` (in the
/// estimate's coordinates, [`GravityReport::theta`]).
pub(crate) fn body_at(
    p: &Prepared,
    model: &bs_dr::Model,
    g: &GravityReport,
    offset: &[f64],
) -> Result<Vec<bs_mesh::Vector3<f64>>, SceneError> {
    let gravity = p.scene.gravity.as_ref().expect("an estimate has a [gravity] table");
    let unknowns = Unknowns::new(gravity, &gravity.estimate.expect("an estimate"));
    let theta: Vec<f64> = g.theta.iter().zip(offset).map(|(t, d)| t + d).collect();
    dead_loads(p, model, Some(&unknowns.gravity_at(&theta)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_names_each_estimate_with_its_unit_and_says_which_the_data_leave_open() {
        let est = |name: &str, estimate, standard_error, determined| ParameterEstimate {
            name: name.into(),
            estimate,
            standard_error,
            prior: 1.0,
            determined,
        };
        let g = GravityReport {
            estimates: vec![
                est("level", 9.6, 0.4, true),
                est("direction", 2.5, 0.7, true),
                est("weight", 0.12, 0.3, false),
            ],
            ..GravityReport::of(&crate::scene::Gravity {
                direction: [0.0, 0.0, -2.0],
                acceleration: 9.81,
                fluid: None,
                estimate: None,
            })
        };
        assert_eq!(g.direction, [0.0, 0.0, -1.0]);
        assert_eq!(
            g.summary("mm"),
            "level 9.60 ± 0.40 mm, direction 2.50 ± 0.70°, weight 12.00 ± 30.00 % (not \
             determined by the data)"
        );
    }
}
