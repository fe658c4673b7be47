//! Landmarks fitted through the boundary the shift comes from.
//!
//! A landmark inside the brain moves because the brain was pushed or pulled at its
//! boundary (the craniotomy); pulling the landmark's own material point (a spring inside the
//! brain) would explain its motion by a point force no brain feels. So the unknown is the
//! displacement `b` of the measurement's node set, in a small basis of smooth fields on it
//! (the three translations and [`BUMPS`] Gaussian bumps along the surface normal), and the
//! fit is a regularised Gauss–Newton problem for the basis amplitudes `a`:
//!
//! `min_a Σ_i w_i |d_i − u(X_i; b(a))|² + μ |a|²`,
//!
//! `d_i` the measured displacement of landmark `i`, `u(X_i; b)` the model's displacement at
//! its material point with `b` imposed, `w_i` Tukey's biweight of `|r_i|/√3` at the robust
//! scale (≥ σ). The Jacobian `∂u(X_i)/∂a` comes from one model solve per basis field at a
//! small amplitude from the reference state, the iterations are chord steps with it, each
//! one model solve warm from the last, and `μ` follows the discrepancy principle counting
//! the fit's degrees of freedom ([`discrepancy`]). The model (its elasticity, the skull
//! contact) decides everything between the boundary and the landmarks. Why a small basis
//! and a penalty on the amplitudes: fifteen landmarks at 1 mm noise determine a handful of
//! boundary amplitudes, not one per node (docs/fit.md measures the choices).

use bs_dr::{Progress, Solution, WarmStart};
use bs_mesh::{Point3, Vector3};
use nalgebra::{DMatrix, DVector};

use crate::SceneError;
use crate::compose::{Composed, loads_of, scale_of};
use crate::measure::MeasuredData;
use crate::prepare::Prepared;
use crate::solve::{SolveSettings, relinearise_at, solve_composed_from};

/// Gaussian normal bumps of the basis (besides the three translations).
pub const BUMPS: usize = 4;
/// Chord steps at most after the Jacobian.
pub const CHORD_STEPS: usize = 4;
/// The amplitude of a basis field in the Jacobian's solves (mm).
const PROBE_MM: f64 = 1.0;
/// A step is halved at most this often when the model cannot carry it.
const MAX_HALVINGS: usize = 4;
/// The residual must fall by this factor per step to go on.
const PROGRESS: f64 = 0.97;

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

/// The basis of boundary fields on the control nodes: three translations, then [`BUMPS`]
/// Gaussian bumps along the outward normal, centred at nodes spread by farthest-point
/// sampling, their width half the mean distance between centres' nearest neighbours.
pub fn basis(p: &Prepared, nodes: &[usize]) -> Vec<Vec<Vector3<f64>>> {
    let mut modes: Vec<Vec<Vector3<f64>>> =
        (0..3).map(|k| vec![Vector3::ith(k, 1.0); nodes.len()]).collect();
    let normals = normals(p, nodes);
    let x: Vec<Point3<f64>> = nodes.iter().map(|&n| p.mesh.nodes[n]).collect();
    let centres = farthest_points(&x, BUMPS.min(x.len()));
    let spacing = centres
        .iter()
        .map(|&i| {
            centres
                .iter()
                .filter(|&&j| j != i)
                .map(|&j| (x[i] - x[j]).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .filter(|d| d.is_finite())
        .sum::<f64>()
        / centres.len().saturating_sub(1).max(1) as f64;
    let width = (0.75 * spacing).max(f64::MIN_POSITIVE);
    for &c in &centres {
        modes.push(
            x.iter()
                .zip(&normals)
                .map(|(xi, n)| n * (-(xi - x[c]).norm_squared() / (2.0 * width * width)).exp())
                .collect(),
        );
    }
    modes
}

/// Outward unit normals at `nodes` from the boundary faces among them.
fn normals(p: &Prepared, nodes: &[usize]) -> Vec<Vector3<f64>> {
    let mut index = vec![usize::MAX; p.mesh.nodes.len()];
    for (k, &n) in nodes.iter().enumerate() {
        index[n] = k;
    }
    let mut out = vec![Vector3::zeros(); nodes.len()];
    let b = p.mesh.boundary();
    for t in &b.surface.triangles {
        let f = t.map(|k| b.volume_node[k]);
        if f.iter().all(|&n| index[n] != usize::MAX) {
            let [a, bb, c] = f.map(|n| p.mesh.nodes[n]);
            let m = (bb - a).cross(&(c - a));
            for n in f {
                out[index[n]] += m;
            }
        }
    }
    out.iter().map(|v| v.try_normalize(0.0).unwrap_or_else(Vector3::z)).collect()
}

/// `k` indices of `x` spread by farthest-point sampling from the one nearest the centroid.
fn farthest_points(x: &[Point3<f64>], k: usize) -> Vec<usize> {
    if x.is_empty() || k == 0 {
        return Vec::new();
    }
    let centroid = Point3::from(x.iter().map(|p| p.coords).sum::<Vector3<f64>>() / x.len() as f64);
    let first =
        (0..x.len()).min_by(|&a, &b| (x[a] - centroid).norm().total_cmp(&(x[b] - centroid).norm()));
    let mut chosen = vec![first.unwrap_or(0)];
    let mut dist: Vec<f64> = x.iter().map(|p| (p - x[chosen[0]]).norm()).collect();
    while chosen.len() < k {
        let next = (0..x.len()).max_by(|&a, &b| dist[a].total_cmp(&dist[b])).unwrap_or(0);
        if dist[next] == 0.0 {
            break;
        }
        chosen.push(next);
        for (d, p) in dist.iter_mut().zip(x) {
            *d = d.min((p - x[next]).norm());
        }
    }
    chosen
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

/// Robust weights (Tukey's biweight of `|r_i|/√3` at the robust scale, ≥ σ) per component,
/// and the inliers' RMS residual per axis.
fn weights(pb: &Problem, r: &DVector<f64>) -> (DVector<f64>, f64) {
    let n = pb.anchors.len();
    let axis = 3f64.sqrt();
    let norms: Vec<f64> = (0..n).map(|i| r.fixed_rows::<3>(3 * i).norm() / axis).collect();
    let s = bs_fit::robust::scale(norms.iter().copied(), pb.sigma, &mut Vec::new());
    let mut w = DVector::zeros(3 * n);
    let (mut sum, mut count) = (0.0, 0usize);
    for (i, &e) in norms.iter().enumerate() {
        let wi = bs_fit::robust::tukey(e, s);
        if wi > 0.0 {
            sum += e * e;
            count += 1;
        }
        w.fixed_rows_mut::<3>(3 * i).fill(wi);
    }
    (w, (sum / count.max(1) as f64).sqrt())
}

/// The step `δa` of the regularised normal equations `(JᵀWJ + μI) δa = JᵀW r − μ a`.
fn step(
    j: &DMatrix<f64>,
    w: &DVector<f64>,
    r: &DVector<f64>,
    a: &DVector<f64>,
    mu: f64,
) -> DVector<f64> {
    let jw = DMatrix::from_fn(j.nrows(), j.ncols(), |i, k| j[(i, k)] * w[i]);
    let mut m = jw.transpose() * j;
    for k in 0..m.nrows() {
        m[(k, k)] += mu;
    }
    let rhs = jw.transpose() * r - a * mu;
    m.cholesky().map_or_else(|| DVector::zeros(a.len()), |c| c.solve(&rhs))
}

/// The discrepancy principle's `μ`, counting the degrees of freedom the fit uses: the
/// smallest `μ` whose predicted weighted residual reaches the noise left after fitting,
/// `Σ w r² = σ² (m − tr H_μ)` (`m` the weighted components, `H_μ` the influence matrix
/// `J (JᵀWJ + μI)⁻¹ JᵀW`), by bisection on `log μ` relative to the normal matrix's scale;
/// 0 when the least-squares step already leaves that much.
fn discrepancy(
    pb: &Problem,
    j: &DMatrix<f64>,
    w: &DVector<f64>,
    r: &DVector<f64>,
    a: &DVector<f64>,
) -> f64 {
    let m: f64 = w.iter().sum::<f64>();
    let jw = DMatrix::from_fn(j.nrows(), j.ncols(), |i, k| j[(i, k)] * w[i]);
    let normal = jw.transpose() * j;
    // Positive when the fit at μ leaves more than the noise.
    let excess = |mu: f64| {
        let left = r - j * step(j, w, r, a, mu);
        let misfit: f64 = left.iter().zip(w.iter()).map(|(x, wi)| wi * x * x).sum();
        let mut reg = normal.clone();
        for k in 0..reg.nrows() {
            reg[(k, k)] += mu;
        }
        let trace = reg.cholesky().map_or(0.0, |c| (c.solve(&normal)).trace());
        misfit - pb.sigma * pb.sigma * (m - trace).max(0.0)
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

/// The boundary field of amplitudes `a`.
fn field(modes: &[Vec<Vector3<f64>>], a: &DVector<f64>) -> Vec<Vector3<f64>> {
    let mut b = vec![Vector3::zeros(); modes.first().map_or(0, Vec::len)];
    for (m, &ak) in modes.iter().zip(a.iter()) {
        for (bi, v) in b.iter_mut().zip(m) {
            *bi += v * ak;
        }
    }
    b
}

/// What the fit did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseInfo {
    /// Model solves (the Jacobian's and the steps').
    pub solves: usize,
    /// RMS residual per axis of the inliers at the answer.
    pub rms: f64,
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
) -> Result<(Solution, f64, InverseInfo), SceneError> {
    let pb = problem(p).expect("called for a scene with landmarks");
    let modes = basis(p, &pb.nodes);
    let mm = 1e-3 / p.scene.units.metres();
    let solves = std::cell::Cell::new(0usize);
    let run = |p: &mut Prepared,
               c: &mut Composed,
               b: &[Vector3<f64>],
               from: Option<&[Vector3<f64>]>,
               observer: &mut dyn FnMut(&Progress)| {
        impose(p, c, &pb.nodes, b)?;
        let start = from.map(|s| WarmStart { state: s, secant: None });
        solves.set(solves.get() + 1);
        solve_composed_from(c, settings, start, observer)
            .map_err(|e| crate::imposed::explain(p.imposed(), e))
    };
    // The state with the boundary at rest: the reference, or the other loads' answer (a
    // body force, another boundary's push) when there are any.
    let base = match loaded_without(p, c, &pb.nodes) {
        true => Some(run(p, c, &vec![Vector3::zeros(); pb.nodes.len()], warm, observer)?.0),
        false => None,
    };
    let at_rest = base.as_ref().map_or_else(
        || DVector::zeros(3 * pb.anchors.len()),
        |s| at_landmarks(&pb, &s.displacements),
    );
    // The Jacobian: one solve per basis field at PROBE_MM from the state at rest.
    let h = PROBE_MM * mm;
    let mut j = DMatrix::zeros(3 * pb.anchors.len(), modes.len());
    for (k, m) in modes.iter().enumerate() {
        let b: Vec<Vector3<f64>> = m.iter().map(|v| v * h).collect();
        let from = base.as_ref().map(|s| s.displacements.as_slice());
        let (s, _) = run(p, c, &b, from, observer)?;
        j.set_column(k, &((at_landmarks(&pb, &s.displacements) - &at_rest) / h));
    }
    let d = DVector::from_iterator(
        3 * pb.measured.len(),
        pb.measured.iter().flat_map(|v| [v.x, v.y, v.z]),
    );
    let mut a = DVector::zeros(modes.len());
    let mut r = &d - &at_rest;
    let (mut w, _) = weights(&pb, &r);
    let mut state: Option<Vec<Vector3<f64>>> =
        warm.map(<[_]>::to_vec).or_else(|| base.map(|s| s.displacements));
    let mut best: Option<(f64, Solution, f64, Vec<Vector3<f64>>)> = None;
    let mut mu = None;
    for _ in 0..CHORD_STEPS {
        let mu = *mu.get_or_insert_with(|| discrepancy(&pb, &j, &w, &r, &a));
        let mut delta = step(&j, &w, &r, &a, mu);
        // A step the model cannot carry (an element would invert) is halved.
        let mut halvings = 0;
        let attempt = loop {
            let b = field(&modes, &(&a + &delta));
            match run(p, c, &b, state.as_deref(), observer) {
                Ok((s, pen)) => break Some((s, pen, b)),
                Err(_) if halvings < MAX_HALVINGS => {
                    delta *= 0.5;
                    halvings += 1;
                }
                Err(e) if best.is_none() => return Err(e),
                Err(_) => break None,
            }
        };
        let Some((solution, penetration, b)) = attempt else { break };
        a += delta;
        r = &d - at_landmarks(&pb, &solution.displacements);
        let (w_new, rms) = weights(&pb, &r);
        w = w_new;
        let previous = best.as_ref().map(|(r0, ..)| *r0);
        if previous.is_none_or(|r0| rms < r0) {
            best = Some((rms, solution.clone(), penetration, b));
        }
        state = Some(solution.displacements);
        if previous.is_some_and(|r0| rms > PROGRESS * r0) {
            break;
        }
    }
    let (rms, solution, penetration, b) = best.expect("one step at least");
    impose(p, c, &pb.nodes, &b)?;
    relinearise_at(c, &solution.displacements);
    let solves = solves.get();
    if let Some(f) = &mut c.fit {
        f.solves = solves;
    }
    Ok((solution, penetration, InverseInfo { solves, rms }))
}
