//! Landmarks fitted through the boundary the shift comes from: the composition of
//! bs-fit's `boundary_fit` with the scene's model. The unknown is the displacement of the
//! measurement's node set in bs-fit's basis of smooth fields; here the basis is imposed on
//! the scene's prescribed components, the Jacobian's probes and the chord steps are model
//! solves (each warm from the last), and the answer is left composed for the
//! uncertainty's tangent. The numerics (weights, steps, the discrepancy principle) and
//! their derivation are bs-fit's.
//!
//! With `[gravity] estimate` the unknowns are the boundary's amplitudes and gravity's
//! named parameters together (one Gauss–Newton problem, each load parameter with its
//! Gaussian prior): landmarks deep in the brain see it sink as a whole, which no field on
//! the craniotomy explains, so the level and the tilt are fitted with the boundary, not
//! before it. Their Jacobian columns are one forward solve each at a small change of the
//! parameter from the state at rest (crate::estimate's probes), and report.json's
//! `gravity` gives each estimate with its standard error from the joint posterior.

use bs_dr::{Progress, Solution, WarmStart};
use bs_fit::boundary_fit::{ChordParams, Priors, basis, chord_fit, field, weights};
use bs_mesh::Vector3;
use nalgebra::{DMatrix, DVector};

use crate::SceneError;
use crate::compose::{Composed, loads_of, scale_of};
use crate::estimate::{GravityReport, Unknowns};
use crate::measure::MeasuredData;
use crate::prepare::Prepared;
use crate::solve::{SolveSettings, relinearise_at, solve_composed_from};

/// The amplitude of a basis field in the Jacobian's solves (mm).
const PROBE_MM: f64 = 1.0;

/// The landmark measurement of a scene: its control nodes, material points, measured
/// displacements and noise.
struct Problem {
    nodes: Vec<usize>,
    measured: Vec<Vector3<f64>>,
    anchors: Vec<bs_fit::Anchor>,
    sigma: f64,
}

/// The landmarks fitted through their node set (beside a scan they name none: they are
/// the gravity estimate's evidence, crate::estimate).
fn problem(p: &Prepared) -> Option<Problem> {
    p.measurements.iter().find_map(|m| match &m.data {
        MeasuredData::Landmarks { .. } if m.nset.is_empty() => None,
        MeasuredData::Landmarks { pairs, anchors, .. } => Some(Problem {
            nodes: p.mesh.node_set(&m.nset).map(<[usize]>::to_vec).unwrap_or_default(),
            measured: pairs.pre.iter().zip(&pairs.intra).map(|(a, b)| b - a).collect(),
            anchors: anchors.iter().map(|(_, a)| *a).collect(),
            sigma: m.sigma,
        }),
        MeasuredData::Surface { .. } => None,
    })
}

/// Whether `p` has landmarks to fit through its boundary.
pub fn has_landmarks(p: &Prepared) -> bool {
    problem(p).is_some()
}

/// Imposes `b` on the control nodes.
fn impose(
    p: &mut Prepared,
    c: &mut Composed,
    nodes: &[usize],
    b: &[Vector3<f64>],
) -> Result<(), SceneError> {
    for (&n, v) in nodes.iter().zip(b) {
        p.prescribed[n] = [Some(v.x), Some(v.y), Some(v.z)];
    }
    let loads = loads_of(p, &p.prescribed, &c.body)?;
    c.load_scale = scale_of(&c.model, &loads, c.fit.as_ref());
    c.loads = loads;
    Ok(())
}

/// Whether anything but the control nodes loads the model: a body force (gravity, a
/// cavity's pressure) or a non-zero prescribed component elsewhere. Then the boundary at
/// rest is not the reference state, and the Jacobian's probes start from its answer.
fn loaded_without(p: &Prepared, c: &Composed, nodes: &[usize]) -> bool {
    let mut control = vec![false; p.mesh.nodes.len()];
    for &n in nodes {
        control[n] = true;
    }
    c.body.iter().any(|f| f.norm() > 0.0)
        || p.prescribed
            .iter()
            .zip(&control)
            .any(|(v, &is)| !is && v.iter().any(|x| x.is_some_and(|x| x != 0.0)))
}

/// The model's displacement at the landmarks, stacked (3 per landmark).
fn at_landmarks(pb: &Problem, u: &[Vector3<f64>]) -> DVector<f64> {
    let mut v = DVector::zeros(3 * pb.anchors.len());
    for (i, a) in pb.anchors.iter().enumerate() {
        let x: Vector3<f64> = a.nodes.iter().zip(&a.weights).map(|(&n, &w)| u[n] * w).sum();
        v.fixed_rows_mut::<3>(3 * i).copy_from(&x);
    }
    v
}

/// What the fit did.
#[derive(Debug, Clone, PartialEq)]
pub struct LandmarkFitInfo {
    /// Model solves (the Jacobian's and the steps').
    pub solves: usize,
    /// RMS residual per axis of the inliers at the answer.
    pub rms: f64,
    /// Gravity's estimate, when the scene estimates it with the boundary.
    pub gravity: Option<GravityReport>,
}

/// Gravity's unknowns of `p`, when it estimates them.
fn load_unknowns(p: &Prepared) -> Option<Unknowns> {
    let g = p.scene.gravity.as_ref()?;
    g.estimate.as_ref().map(|e| Unknowns::new(g, e))
}

/// Fits the scene's landmarks (see the module documentation): the answer's solution and
/// largest penetration, and what the fit did. `warm`: a converged state to start the
/// steps from.
pub fn solve(
    p: &mut Prepared,
    c: &mut Composed,
    settings: &SolveSettings,
    warm: Option<&[Vector3<f64>]>,
    observer: &mut dyn FnMut(&Progress),
) -> Result<(Solution, f64, LandmarkFitInfo), SceneError> {
    let pb = problem(p).expect("called for a scene with landmarks");
    let modes = basis(&p.mesh, &pb.nodes);
    let loads = load_unknowns(p);
    let (nb, nl) = (modes.len(), loads.as_ref().map_or(0, |u| u.params.len()));
    let mm = 1e-3 / p.scene.units.metres();
    let solves = std::cell::Cell::new(0usize);
    let run = |p: &mut Prepared,
               c: &mut Composed,
               b: &[Vector3<f64>],
               theta: &[f64],
               from: Option<&[Vector3<f64>]>,
               observer: &mut dyn FnMut(&Progress)| {
        if let Some(u) = &loads {
            crate::estimate::gravity_for(p, c, u, theta)?;
        }
        impose(p, c, &pb.nodes, b)?;
        let start = from.map(|s| WarmStart { state: s, secant: None });
        solves.set(solves.get() + 1);
        solve_composed_from(c, settings, start, observer)
            .map_err(|e| crate::imposed::explain(p.imposed(), e))
    };
    let rest = vec![Vector3::zeros(); pb.nodes.len()];
    let theta0 = vec![0.0; nl];
    // The state with the boundary at rest: the reference, or the other loads' answer (a
    // body force, another boundary's push) when there are any.
    let base = match loaded_without(p, c, &pb.nodes) {
        true => Some(run(p, c, &rest, &theta0, warm, observer)?.0),
        false => None,
    };
    let at_rest = base.as_ref().map_or_else(
        || DVector::zeros(3 * pb.anchors.len()),
        |s| at_landmarks(&pb, &s.displacements),
    );
    // The Jacobian: one solve per basis field at PROBE_MM from the state at rest, and one
    // per load parameter at its probe with the boundary at rest.
    let h = PROBE_MM * mm;
    let probes = loads.as_ref().map_or_else(Vec::new, |u| u.probes(mm));
    let mut j = DMatrix::zeros(3 * pb.anchors.len(), nb + nl);
    for k in 0..nb + nl {
        let (b, theta, step) = match k < nb {
            true => (modes[k].iter().map(|v| v * h).collect(), theta0.clone(), h),
            false => {
                let mut t = theta0.clone();
                t[k - nb] = probes[k - nb];
                (rest.clone(), t, probes[k - nb])
            }
        };
        let from = base.as_ref().map(|s| s.displacements.as_slice());
        let (s, _) = run(p, c, &b, &theta, from, observer)?;
        j.set_column(k, &((at_landmarks(&pb, &s.displacements) - &at_rest) / step));
    }
    let d = DVector::from_iterator(
        3 * pb.measured.len(),
        pb.measured.iter().flat_map(|v| [v.x, v.y, v.z]),
    );
    let mut state: Option<Vec<Vector3<f64>>> =
        warm.map(<[_]>::to_vec).or_else(|| base.map(|s| s.displacements));
    let sd = loads.as_ref().map_or(&[][..], |u| u.prior_sd.as_slice());
    let fit = chord_fit::<_, SceneError>(
        &d,
        pb.sigma,
        &j,
        &at_rest,
        &Priors { sd },
        &ChordParams::default(),
        &mut |a| {
            let b = field(&modes, &a.rows(0, nb).into_owned());
            let theta: Vec<f64> = a.rows(nb, nl).iter().copied().collect();
            let (s, pen) = run(p, c, &b, &theta, state.as_deref(), observer)?;
            state = Some(s.displacements.clone());
            let at = at_landmarks(&pb, &s.displacements);
            Ok((at, (s, pen, b, theta)))
        },
    )?;
    let (rms, (solution, penetration, b, theta)) = (fit.rms, fit.answer);
    if let Some(u) = &loads {
        crate::estimate::gravity_for(p, c, u, &theta)?;
    }
    impose(p, c, &pb.nodes, &b)?;
    relinearise_at(c, &solution.displacements);
    let solves = solves.get();
    if let Some(f) = &mut c.fit {
        f.solves = solves;
    }
    let gravity = loads.as_ref().map(|u| {
        let cov = fit.covariance.view((nb, nb), (nl, nl)).into_owned();
        let left = &d - at_landmarks(&pb, &solution.displacements);
        let inliers = weights(&left, pb.sigma).0.iter().filter(|&&w| w > 0.0).count() / 3;
        GravityReport {
            solves,
            landmark_inliers: inliers,
            ..crate::estimate::estimated(u, &u.gravity_at(&theta), &theta, &cov)
        }
    });
    Ok((solution, penetration, LandmarkFitInfo { solves, rms, gravity }))
}
