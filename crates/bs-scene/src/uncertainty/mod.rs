//! How far to trust a fitted answer: σ of the fitted displacement per node, from the
//! fit's linearised posterior (docs/uncertainty.md).
//!
//! Each sample draws what the fit was not told exactly ([`draws`]: every scan point's
//! noise, the rigid correction that noise leaves in the bone points, gravity's estimated
//! parameters from their posterior covariance) and pushes the change it makes to the
//! equations through the converged tangent (one GMRES solve each, bs-dr's
//! [`bs_dr::Response`]): the sample's deviation of the answer. The per-axis σ is the root
//! mean square of the deviations; its relative error is about `1/√(2N)` for `N` samples
//! (13 % at 32), whatever the correlation between nodes. The solves stop loosely; what that
//! leaves out is measured on the first batch and scaled back ([`truncation`]).
//!
//! What it captures: the data's noise and the load parameters the data left uncertain,
//! through the model as fitted. What it cannot: the model's own error (a wrong
//! constitutive law, a wrong fixed set, unmodelled heterogeneity), which docs/uncertainty.md
//! measures against truths the fit does not know.

mod draws;
pub mod held_out;
pub mod sigma;
pub mod truncation;

use std::time::Instant;

use bs_mesh::Vector3;
use bs_mesh::rng::SplitMix64;
use serde::{Deserialize, Serialize};

use crate::SceneError;
use crate::run::{Run, Solved};
use crate::scene::SolverKind;
use draws::Draws;
pub use held_out::{HeldOut, HeldOutScale};
pub use sigma::Uncertainty;

/// How the σ is sampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UncertaintyParams {
    /// Samples (at least 2).
    pub samples: usize,
    /// The seed of the draws (the same seed gives the same σ).
    pub seed: u64,
    /// GMRES's relative residual per response, in (0, 1). A loose solve biases σ low (at
    /// 1e-2 by 3 % on fixtures/fit and 17 % on fixtures/fit-gravity, mean over the nodes),
    /// so above [`truncation::REFINED`] the first batch is refined to it and σ scaled by
    /// what that adds. The default 1e-2 so scaled leaves the deep nodes' mean σ 0.6 % above
    /// its converged value on average over the calibration study's 20 fits (−4.6 to
    /// +8.2 %; unscaled −6.9 %, −14.3 to +2.8 %); 1e-3 is within 1.2 % unscaled on the
    /// fixtures, at 1.7–1.9× the time (docs/uncertainty.md, "The solves' tolerance").
    pub rtol: f64,
}

/// The tolerance scale of reports written before they carried it.
fn one() -> f64 {
    1.0
}

/// The relative residual of reports written before they carried it.
fn default_rtol() -> f64 {
    UncertaintyParams::default().rtol
}

impl Default for UncertaintyParams {
    fn default() -> Self {
        UncertaintyParams { samples: 32, seed: 1, rtol: 1e-2 }
    }
}

/// report.json's `uncertainty`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UncertaintyReport {
    /// Samples, GMRES iterations of their responses, and seconds beyond the fit.
    pub samples: usize,
    pub iterations: usize,
    pub seconds: f64,
    /// GMRES's relative residual per sample ([`UncertaintyParams::rtol`]).
    #[serde(default = "default_rtol")]
    pub tolerance: f64,
    /// The factor every σ here is scaled by for the solves' stop at `tolerance`: the first
    /// batch refined to [`truncation::REFINED`], the root of its energy ratio (1 when the
    /// tolerance is that tight; docs/uncertainty.md, "The solves' tolerance").
    #[serde(default = "one")]
    pub tolerance_scale: f64,
    /// What the samples drew: `scan noise`, `rigid correction from the bone points' noise`,
    /// `gravity's estimated parameters`; and `the scale from N held-out landmarks` when
    /// they scaled it (`held_out`). The model's own error is not drawn.
    pub parts: Vec<String>,
    /// The largest total σ (mesh units), the node id where it is and the node's reference
    /// position (scene frame).
    pub max_sigma: f64,
    pub max_node: u64,
    pub max_at: [f64; 3],
    /// The mean total σ over the nodes.
    pub mean_sigma: f64,
    /// Per landmark (file order): σ along x, y, z and in total.
    pub landmarks: Vec<LandmarkSigma>,
    /// What `[uncertainty] held_out` said and the factor σ was scaled by (every σ above is
    /// scaled); none without held-out landmarks.
    #[serde(default)]
    pub held_out: Option<HeldOutScale>,
}

/// σ at one landmark.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LandmarkSigma {
    /// Its row in the landmark files (from 0).
    pub index: usize,
    pub sigma: [f64; 3],
    pub total: f64,
}

impl UncertaintyReport {
    /// The report of `u` on the mesh of `run`.
    pub fn of(run: &Run, u: &Uncertainty) -> UncertaintyReport {
        let mesh = &run.prepared.mesh;
        let n = u.sigma.len();
        let (max_node, max_sigma) = (0..n)
            .map(|a| (a, u.total(a)))
            .fold((0, 0.0f64), |m, (a, s)| if s > m.1 { (a, s) } else { m });
        let at = mesh.nodes.get(max_node).map_or([0.0; 3], |x| [x.x, x.y, x.z]);
        let landmarks = u
            .landmarks
            .iter()
            .enumerate()
            .map(|(index, s)| LandmarkSigma {
                index,
                sigma: *s,
                total: (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt(),
            })
            .collect();
        UncertaintyReport {
            samples: u.samples,
            iterations: u.iterations,
            seconds: u.seconds,
            tolerance: u.tolerance,
            tolerance_scale: u.tolerance_scale,
            parts: u.parts.clone(),
            max_sigma,
            max_node: mesh.node_ids.get(max_node).copied().unwrap_or(max_node as u64 + 1),
            max_at: at,
            mean_sigma: if n == 0 {
                0.0
            } else {
                (0..n).map(|a| u.total(a)).sum::<f64>() / n as f64
            },
            landmarks,
            held_out: u.held_out.clone(),
        }
    }
}

/// Whether `run`'s scene has something fitted that [`sample`] can draw (a scan, or
/// gravity's estimated parameters) and held-out landmarks it can read. `Err` names what is
/// missing or wrong.
pub fn check(run: &Run) -> Result<(), SceneError> {
    fitted(run)?;
    HeldOut::read(&run.prepared).map(|_| ())
}

/// The first half of [`check`]: something fitted to draw.
fn fitted(run: &Run) -> Result<(), SceneError> {
    let p = &run.prepared;
    let scans = p
        .measurements
        .iter()
        .any(|m| matches!(m.data, crate::measure::MeasuredData::Surface { .. }));
    if scans || crate::estimate::estimates(p) {
        return Ok(());
    }
    let why = if p.measurements.is_empty() {
        "the scene fits nothing (no [[measurement]]), so the answer has no fitted \
         uncertainty; add a scan as a [[measurement]], or run without --uncertainty"
    } else {
        "landmarks fitted through a set are not sampled yet: add the scan they were taken \
         with as a [[measurement]], or run without --uncertainty"
    };
    Err(SceneError::Scene { file: p.path.clone(), message: format!("--uncertainty: {why}") })
}

/// σ of `solved`, the answer of `run` ([`check`] first): `params.samples` draws pushed
/// through the converged tangent (module documentation).
pub fn sample(
    run: &mut Run,
    solved: &Solved,
    params: &UncertaintyParams,
) -> Result<Uncertainty, SceneError> {
    fitted(run)?;
    if !(params.rtol > 0.0 && params.rtol < 1.0) {
        return Err(SceneError::Scene {
            file: run.prepared.path.clone(),
            message: format!(
                "--uncertainty-tolerance {}: give a relative residual between 0 and 1 \
                 (1e-2 by default; 1e-3 for σ within about 1 % of its converged value)",
                params.rtol
            ),
        });
    }
    if params.samples < 2 {
        return Err(SceneError::Scene {
            file: run.prepared.path.clone(),
            message: format!(
                "--uncertainty {}: give at least 2 samples (32 gives σ to about 13 %)",
                params.samples
            ),
        });
    }
    let started = Instant::now();
    let settings = crate::solve::SolveSettings { kind: SolverKind::NewtonKrylov, ..run.settings };
    let c = &mut run.composed;
    crate::solve::prepare_solver(c, &settings)?;
    let p = &run.prepared;
    let u = &solved.solution.displacements;
    let gravity = solved.gravity.as_ref();
    let data_used = solved.data_unused.is_none();
    if !data_used && gravity.is_none_or(|g| g.theta.is_empty()) {
        return Err(SceneError::Scene {
            file: run.prepared.path.clone(),
            message: format!(
                "--uncertainty: the measurements were not used ({}), so the answer has no \
                 fitted uncertainty; run without --uncertainty, or fix the data",
                solved.data_unused.as_deref().unwrap_or_default()
            ),
        });
    }
    let fit = c.fit.as_ref().filter(|_| data_used);
    let draws = Draws::new(p, &c.model, fit, u, gravity)?;
    let held_out = HeldOut::read(p)?;
    let mut anchors = landmark_anchors(p);
    let scene_landmarks = anchors.len();
    anchors.extend(held_out.iter().flat_map(|h| h.anchors.iter().copied()));
    let n = u.len();
    let mut m2 = vec![Vector3::<f64>::zeros(); n];
    let mut l2 = vec![Vector3::<f64>::zeros(); anchors.len()];
    let mut rng = SplitMix64::new(params.seed);
    let batch = bs_dr::nk::BATCH.min(params.samples);
    let (mut changes, mut dus) = (vec![vec![Vector3::zeros(); n]; batch], vec![vec![]; batch]);
    dus.iter_mut().for_each(|d| *d = vec![Vector3::zeros(); n]);
    let mut data = c.fit.as_ref().filter(|_| data_used).map(|f| f.fits.clone());
    let mut none = bs_dr::NoData;
    let data: &mut dyn bs_dr::DataTerm = match &mut data {
        Some(f) => f,
        None => &mut none,
    };
    let mut no_contact = bs_dr::NoContact;
    let contact: &mut dyn bs_dr::Contact = match &mut c.contact {
        Some(sc) => sc,
        None => &mut no_contact,
    };
    let prep = c.preparation.as_ref().expect("prepared above");
    let nk = crate::solve::newton_krylov(&settings);
    let model = &c.model;
    let (iterations, truncation) = nk
        .with_response(model, &c.loads, prep, u, contact, data, |r| {
            let (mut left, mut truncation) = (params.samples, None);
            while left > 0 {
                let m = left.min(batch);
                for change in &mut changes[..m] {
                    draws.residual_change(model, &mut rng, change)?;
                }
                r.solve_all(&changes[..m], &mut dus[..m], params.rtol)
                    .map_err(bs_dr::SolveError::from)?;
                for du in &dus[..m] {
                    m2.iter_mut().zip(du).for_each(|(m, d)| *m += d.component_mul(d));
                    for (l, a) in l2.iter_mut().zip(&anchors) {
                        let d: Vector3<f64> =
                            a.nodes.iter().zip(&a.weights).map(|(&k, &w)| du[k] * w).sum();
                        *l += d.component_mul(&d);
                    }
                }
                if truncation.is_none() {
                    let s = truncation::scale(r, &changes[..m], &mut dus[..m], params.rtol);
                    truncation = Some(s.map_err(bs_dr::SolveError::from)?);
                }
                left -= m;
            }
            Ok::<_, SceneError>((r.gmres_iterations(), truncation.unwrap_or(1.0)))
        })
        .map_err(bs_dr::SolveError::from)??;
    m2.iter_mut().chain(l2.iter_mut()).for_each(|v| *v *= truncation);
    let samples = params.samples as f64;
    let held_out = held_out.map(|h| {
        let var: Vec<Vector3<f64>> = l2[scene_landmarks..].iter().map(|v| v / samples).collect();
        held_out::scale(&h.files, &h.misses(u), &var, h.sigma)
    });
    let factor = held_out.as_ref().map_or(1.0, |h| h.scale);
    let rms = |v: &Vector3<f64>| {
        let s = (v / samples).map(|x| x.sqrt() * factor);
        [s.x, s.y, s.z]
    };
    let mut parts = draws.parts();
    if let Some(h) = held_out.as_ref().filter(|h| h.scale > 1.0) {
        parts.push(format!("the scale from {} held-out landmarks", h.landmarks));
    }
    Ok(Uncertainty {
        sigma: m2.iter().map(rms).collect(),
        landmarks: l2[..scene_landmarks].iter().map(rms).collect(),
        held_out,
        parts,
        samples: params.samples,
        iterations,
        seconds: started.elapsed().as_secs_f64(),
        tolerance: params.rtol,
        tolerance_scale: truncation.sqrt(),
    })
}

/// The material points of the scene's landmarks (file order; none without landmarks).
fn landmark_anchors(p: &crate::prepare::Prepared) -> Vec<bs_fit::Anchor> {
    p.measurements
        .iter()
        .filter_map(|m| match &m.data {
            crate::measure::MeasuredData::Landmarks { anchors, .. } => {
                Some(anchors.iter().map(|(_, a)| *a))
            }
            _ => None,
        })
        .flatten()
        .collect()
}
