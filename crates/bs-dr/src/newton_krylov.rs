//! The fast steady-state solver: a semismooth Newton–Krylov method with the two-level
//! preconditioner of `K₀` and the kinematic contact linearised on its active set.
//!
//! Each iteration solves the linearised equilibrium with GMRES, applying the Jacobian of the
//! internal forces matrix-free (a forward difference of [`Model::internal_forces_into`], so
//! every element technology is linearised exactly as its force kernel) and preconditioning
//! with [`TwoLevel`], which depends only on mesh, materials and fixed components and is
//! prepared once ([`NewtonKrylov::prepare`]).
//!
//! # Contact
//!
//! The contact stays the paper's: frictionless, parameter-free, a node either inside the
//! cavity or on its surface. Its equilibrium conditions are written as the fixed point of the
//! projection that Dynamic Relaxation iterates, `x_a = Proj(x_a + γ_a r_a)` for every contact
//! node (`r_a` its out-of-balance force, `γ_a = 3 / tr K₀,aa` a nodal compliance): a node
//! whose trial point `x_a + γ_a r_a` lies inside is free; one whose trial point projects onto a
//! face is held on the face's plane and free along it; onto an edge, held on the edge's line;
//! onto a vertex, held at the vertex. This is the semismooth Newton method for the natural
//! residual of the contact conditions (the primal–dual active-set method with the surface's
//! non-smooth features): the active set and the feature of every contact node are re-chosen
//! every iteration from the current forces, so contact opens and closes, and nodes slide over
//! edges, without any penalty parameter. The preconditioner and GMRES run on the subspace the
//! active constraints leave free.
//!
//! # Globalisation and termination
//!
//! The first iteration applies the whole prescribed displacement through the linearised
//! system (the prescribed components move, the others follow the linear response), so no
//! element is crushed by a jump of the boundary. A backtracking line search on the largest
//! component of the natural residual (in length units) accepts a step only if it decreases
//! the residual; a step that inverts an element is halved. The linear solves are inexact
//! (Eisenstat–Walker forcing between [`NewtonKrylovParams::forcing_min`] and
//! [`NewtonKrylovParams::forcing_max`], never tighter than the tolerance needs). The iteration stops when the last correction
//! `max|Δu|` is below the tolerance with the prescribed displacement fully applied and the
//! active set and features unchanged: with the iteration converging superlinearly the error
//! of the answer is a fraction of that last correction, which is reported as the error
//! estimate. Finally [`Contact::enforce`] moves any node still outside (by less than the
//! tolerance) onto the surface, as Dynamic Relaxation's last step would.

use std::time::Instant;

use bs_mesh::{Point3, Vector3};
use rayon::prelude::*;

use crate::assembly::{Inversion, Workspace};
use crate::contact::{Contact, ContactReport, SurfaceFeature};
use crate::linalg::krylov::Gmres;
use crate::linalg::sparse::max_abs;
use crate::linalg::twolevel::{Constraints, Projector, TwoLevel, TwoLevelParams};
use crate::loads::Loads;
use crate::model::Model;
use crate::solver::{
    Breakdown, Progress, Report, Solution, SolveError, Solver, check_param, load_scale,
};

/// Parameters of [`NewtonKrylov`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonKrylovParams {
    /// Convergence tolerance on the last Newton correction, relative to the load scale (the
    /// largest prescribed displacement component, or the bounding-box diagonal if none).
    /// Default 1e-6.
    pub tolerance: f64,
    /// Newton iterations allowed. Default 60.
    pub max_iterations: usize,
    /// GMRES iterations allowed per Newton iteration. Default 200.
    pub max_linear_iterations: usize,
    /// GMRES restart length. Default 40.
    pub restart: usize,
    /// Largest relative residual asked of a linear solve (early iterations). Default 0.1.
    pub forcing_max: f64,
    /// Relative residual asked of a linear solve while the contact active set still changes
    /// in more than 1% of the contact nodes. Default 0.5.
    pub forcing_active_set: f64,
    /// Smallest relative residual asked of a linear solve. Default 1e-2 (a correction then
    /// carries an error of about 1% of itself, far below the tolerance near convergence).
    pub forcing_min: f64,
    /// Divergence bound on `max|u|` as a multiple of the load scale. Default 100.
    pub divergence_factor: f64,
    /// The preconditioner's parameters.
    pub preconditioner: TwoLevelParams,
}

impl Default for NewtonKrylovParams {
    fn default() -> Self {
        NewtonKrylovParams {
            tolerance: 1e-6,
            max_iterations: 60,
            max_linear_iterations: 200,
            restart: 40,
            forcing_max: 0.1,
            forcing_active_set: 0.5,
            forcing_min: 1e-2,
            divergence_factor: 100.0,
            preconditioner: TwoLevelParams::default(),
        }
    }
}

/// The semismooth Newton–Krylov solver (see the module documentation).
#[derive(Debug, Clone, Copy, Default)]
pub struct NewtonKrylov {
    /// Parameters.
    pub params: NewtonKrylovParams,
}

/// What [`NewtonKrylov::prepare`] computes: everything that depends only on the mesh, the
/// materials and which components are prescribed (not on their values), so it can be
/// computed before the loads are known and reused for any number of solves.
#[derive(Debug)]
pub struct Preparation {
    preconditioner: TwoLevel,
    /// `γ_a = 3 / tr K₀,aa`, the nodal compliance that scales forces to lengths.
    compliance: Vec<f64>,
    /// Which components were fixed when it was built.
    pattern: Vec<[bool; 3]>,
}

impl Preparation {
    /// The preconditioner.
    pub fn preconditioner(&self) -> &TwoLevel {
        &self.preconditioner
    }

    /// Whether this preparation fits `loads` (same prescribed components).
    pub fn fits(&self, loads: &Loads) -> bool {
        self.pattern.len() == loads.node_count()
            && self
                .pattern
                .iter()
                .enumerate()
                .all(|(a, c)| (0..3).all(|k| c[k] == loads.is_constrained(a, k)))
    }
}

/// The fixed components of `loads` as a nodal projector.
fn fixed_projector(loads: &Loads) -> Projector {
    let n = loads.node_count();
    let mut p = Projector::free(n);
    let axes = [Vector3::x(), Vector3::y(), Vector3::z()];
    let mut dirs = Vec::with_capacity(3);
    for a in 0..n {
        dirs.clear();
        for (k, axis) in axes.iter().enumerate() {
            if loads.is_constrained(a, k) {
                dirs.push(*axis);
            }
        }
        if !dirs.is_empty() {
            p.set(a, &dirs);
        }
    }
    p
}

/// Counts and times of the work done by a solve.
#[derive(Debug, Clone, Copy, Default)]
struct Work {
    forces: usize,
    linear: usize,
    time: Breakdown,
}

/// Internal forces with the count and time kept.
fn forces(
    model: &Model,
    u: &[Vector3<f64>],
    ws: &mut Workspace,
    f: &mut [Vector3<f64>],
    work: &mut Work,
) -> Result<(), Inversion> {
    let t = Instant::now();
    work.forces += 1;
    let r = model.internal_forces_into(u, ws, f);
    work.time.forces += t.elapsed();
    r
}

/// The contact state of one node for one iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Active {
    Free,
    Held {
        target: Point3<f64>,
        feature: SurfaceFeature,
    },
    /// Held on the line where the planes of two faces meet: a node that alternated between
    /// the two faces, whose equilibrium is on their common edge. Each plane is a normal and
    /// a point of it.
    Crease {
        a: (Vector3<f64>, Point3<f64>),
        b: (Vector3<f64>, Point3<f64>),
    },
}

impl Active {
    fn same_as(&self, other: &Active) -> bool {
        match (self, other) {
            (Active::Free, Active::Free) => true,
            (Active::Held { feature: a, .. }, Active::Held { feature: b, .. }) => match (a, b) {
                (SurfaceFeature::Face(n), SurfaceFeature::Face(m))
                | (SurfaceFeature::Edge(n), SurfaceFeature::Edge(m))
                | (
                    SurfaceFeature::Curved { normal: n, .. },
                    SurfaceFeature::Curved { normal: m, .. },
                ) => n.dot(m).abs() > 1.0 - 1e-6,
                (SurfaceFeature::Vertex, SurfaceFeature::Vertex) => true,
                _ => false,
            },
            (Active::Crease { a, b }, Active::Crease { a: c, b: d }) => {
                a.0.dot(&c.0) > 1.0 - 1e-6 && b.0.dot(&d.0) > 1.0 - 1e-6
            }
            _ => false,
        }
    }

    /// The crease of two faces a node alternated between: `previous` and `now` both held on
    /// faces with different normals (and not nearly opposite ones).
    fn crease(previous: &Active, now: &Active) -> Option<Active> {
        match (previous, now) {
            (
                Active::Held { target: r1, feature: SurfaceFeature::Face(n1) },
                Active::Held { target: r2, feature: SurfaceFeature::Face(n2) },
            ) if n1.dot(n2) < 1.0 - 1e-6 && n1.dot(n2) > -0.5 => {
                Some(Active::Crease { a: (*n1, *r1), b: (*n2, *r2) })
            }
            _ => None,
        }
    }

    /// Whether the out-of-balance force `push` (outward) at a crease node still presses on
    /// both planes: its components on the two normals are both non-negative.
    fn presses_on_both(&self, push: &Vector3<f64>) -> bool {
        let Active::Crease { a, b } = self else { return false };
        let (na, nb) = (a.0, b.0);
        let c = na.dot(&nb);
        let det = 1.0 - c * c;
        if det <= 1e-12 {
            return false;
        }
        let (pa, pb) = (na.dot(push), nb.dot(push));
        let mu_a = (pa - c * pb) / det;
        let mu_b = (pb - c * pa) / det;
        mu_a >= 0.0 && mu_b >= 0.0
    }
}

impl NewtonKrylov {
    /// A solver with the given parameters.
    pub fn new(params: NewtonKrylovParams) -> Self {
        NewtonKrylov { params }
    }

    fn validate(&self) -> Result<(), SolveError> {
        let p = &self.params;
        check_param("tolerance", p.tolerance, p.tolerance > 0.0, "must be > 0")?;
        check_param(
            "max_iterations",
            p.max_iterations as f64,
            p.max_iterations >= 1,
            "must be >= 1",
        )?;
        check_param(
            "max_linear_iterations",
            p.max_linear_iterations as f64,
            p.max_linear_iterations >= 1,
            "must be >= 1",
        )?;
        check_param("restart", p.restart as f64, p.restart >= 1, "must be >= 1")?;
        check_param(
            "forcing_max",
            p.forcing_max,
            p.forcing_max > 0.0 && p.forcing_max < 1.0,
            "must lie in (0, 1)",
        )?;
        check_param(
            "forcing_active_set",
            p.forcing_active_set,
            p.forcing_active_set > 0.0 && p.forcing_active_set < 1.0,
            "must lie in (0, 1)",
        )?;
        check_param(
            "forcing_min",
            p.forcing_min,
            p.forcing_min > 0.0 && p.forcing_min <= p.forcing_max,
            "must lie in (0, forcing_max]",
        )?;
        check_param(
            "divergence_factor",
            p.divergence_factor,
            p.divergence_factor > 1.0,
            "must be > 1",
        )?;
        let t = &p.preconditioner;
        check_param("aggregate_size", t.aggregate_size, t.aggregate_size > 0.0, "must be > 0")?;
        check_param("degree", t.degree as f64, t.degree >= 1, "must be >= 1")?;
        check_param("lower", t.lower, t.lower > 0.0 && t.lower < 1.0, "must lie in (0, 1)")?;
        Ok(())
    }

    /// Builds the preconditioner for `model` with the prescribed components of `loads` (their
    /// values are not used).
    pub fn prepare(&self, model: &Model, loads: &Loads) -> Result<Preparation, SolveError> {
        self.validate()?;
        let n = model.node_count();
        if loads.node_count() != n {
            return Err(SolveError::LoadMismatch { expected: n, got: loads.node_count() });
        }
        let fixed = fixed_projector(loads);
        let k0 = model.linear_stiffness();
        let (x, h) = (model.reference(), model.mean_edge());
        let preconditioner = TwoLevel::new(k0, x, h, &fixed, self.params.preconditioner)
            .map_err(|e| SolveError::Preconditioner { reason: e.to_string() })?;
        let k = preconditioner.stiffness();
        let compliance = (0..n)
            .into_par_iter()
            .map(|a| {
                let tr = k.diagonal(a).trace();
                if tr > 0.0 { 3.0 / tr } else { 0.0 }
            })
            .collect();
        let pattern = (0..n).map(|a| std::array::from_fn(|k| loads.is_constrained(a, k))).collect();
        Ok(Preparation { preconditioner, compliance, pattern })
    }

    /// Solves with a preparation from [`prepare`](Self::prepare) for the same model and the
    /// same prescribed components.
    pub fn solve_prepared(
        &self,
        model: &Model,
        loads: &Loads,
        prep: &Preparation,
        contact: &mut dyn Contact,
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solution, SolveError> {
        self.validate()?;
        let start = Instant::now();
        let p = self.params;
        let n = model.node_count();
        if loads.node_count() != n {
            return Err(SolveError::LoadMismatch { expected: n, got: loads.node_count() });
        }
        if !prep.fits(loads) {
            return Err(SolveError::Unsupported {
                solver: "newton-krylov",
                what: "a preparation built for other prescribed components",
                fix: "prepare again with these loads",
            });
        }
        let contact_nodes: Vec<usize> = contact.nodes().to_vec();
        if contact_nodes.iter().any(|&a| a >= n) {
            return Err(SolveError::Unsupported {
                solver: "newton-krylov",
                what: "contact on a node outside the mesh",
                fix: "give the contact indices of mesh nodes",
            });
        }
        let scale = load_scale(model, loads);
        let tol = p.tolerance * scale;
        let limit = p.divergence_factor * scale;
        let reference = model.reference();
        let tl = &prep.preconditioner;
        let gamma = &prep.compliance;
        let mut work = Work::default();
        let mut ws = model.workspace();
        let mut cons: Constraints = tl.constraints();
        let fixed_pi = tl.constraints().projector;
        let mut tl_scratch = tl.scratch();
        let mut gmres = Gmres::new(n, p.restart);

        let mut u = vec![Vector3::<f64>::zeros(); n];
        let mut f = u.clone();
        let mut trial_u = u.clone();
        let mut trial_f = u.clone();
        let mut fd = u.clone();
        let mut up = u.clone();
        let mut rhs = u.clone();
        let mut delta = u.clone();
        let mut particular = u.clone();
        let mut positions: Vec<Point3<f64>> = reference.to_vec();
        // The prescribed displacements still to apply (the full values at first).
        let mut remaining: Vec<Vector3<f64>> = (0..n)
            .map(|a| {
                Vector3::from_fn(
                    |k, _| if loads.is_constrained(a, k) { loads.value(a, k) } else { 0.0 },
                )
            })
            .collect();
        let mut active = vec![Active::Free; contact_nodes.len()];
        let mut previous = active.clone();
        let mut before_previous = active.clone();
        let mut dirs = [Vector3::zeros(); 3];
        let mut held = [Vector3::zeros(); 3];
        let mut springs: Vec<(usize, f64)> = Vec::new();

        if let Err(inv) = forces(model, &u, &mut ws, &mut f, &mut work) {
            return Err(inverted(0, inv));
        }
        let mut phi = f64::INFINITY;
        let mut eta = p.forcing_max;
        let mut max_penetration = 0.0f64;
        let mut err = f64::INFINITY;
        let mut applied = 0.0f64;
        let mut is_contact = vec![false; n];
        for &a in &contact_nodes {
            is_contact[a] = true;
        }

        for iteration in 1..=p.max_iterations {
            // 1. Active set and features from the trial points x + γ r.
            let contact_start = Instant::now();
            let mut changes = 0usize;
            let mut cycling = 0usize;
            for (k, &a) in contact_nodes.iter().enumerate() {
                let x = reference[a] + u[a];
                let push = -(fixed_pi.matrix[a] * f[a]);
                // A node on a crease stays there while the force presses it on both faces.
                if previous[k].presses_on_both(&push) {
                    active[k] = previous[k];
                    continue;
                }
                let y = x + push * gamma[a];
                let state = match contact.project(k, &y) {
                    Some(proj) if proj.outside => {
                        Active::Held { target: proj.point, feature: proj.feature }
                    }
                    Some(_) => Active::Free,
                    None => {
                        return Err(SolveError::Unsupported {
                            solver: "newton-krylov",
                            what: "a contact handler that cannot project points",
                            fix: "use a handler with exact projection, or the Dynamic Relaxation solver",
                        });
                    }
                };
                let mut state = state;
                if !state.same_as(&previous[k]) {
                    changes += 1;
                    // Back to the feature of two iterations ago: the node alternates between
                    // two faces, or between contact and freedom. Between two faces its
                    // equilibrium is on their edge: hold it there. Otherwise full steps would
                    // repeat the cycle, damped ones converge.
                    if state.same_as(&before_previous[k]) {
                        match Active::crease(&previous[k], &state) {
                            Some(c) => state = c,
                            None => cycling += 1,
                        }
                    }
                }
                active[k] = state;
            }
            // Constraints and the particular displacement: prescribed values still to apply,
            // and the normal components that put held nodes on their feature.
            particular.copy_from_slice(&remaining);
            springs.clear();
            for (k, &a) in contact_nodes.iter().enumerate() {
                match active[k] {
                    Active::Free => {
                        tl.constrain(&mut cons, a, &[], &mut held);
                    }
                    Active::Crease { a: pa, b: pb } => {
                        let m = tl.constrain(&mut cons, a, &[pa.0, pb.0], &mut held);
                        // A point of the line: the least-norm move onto both planes.
                        let x = reference[a] + u[a];
                        let (ga, gb) = (pa.0.dot(&(pa.1 - x)), pb.0.dot(&(pb.1 - x)));
                        let c = pa.0.dot(&pb.0);
                        let det = (1.0 - c * c).max(1e-12);
                        let q = x + pa.0 * ((ga - c * gb) / det) + pb.0 * ((gb - c * ga) / det);
                        particular[a] +=
                            held[..m].iter().fold(Vector3::zeros(), |s, d| s + d * d.dot(&(q - x)));
                    }
                    Active::Held { target, feature } => {
                        if let SurfaceFeature::Curved { curvature, .. } = feature {
                            // The projection onto a surface of curvature κ from a trial point
                            // s beyond it shrinks tangential motions by 1/(1 + κs): in the
                            // linearised equilibrium, a tangential spring κ s / γ.
                            let y = reference[a] + u[a] - fixed_pi.matrix[a] * f[a] * gamma[a];
                            let s = (y - target).norm();
                            springs.push((a, curvature * s / gamma[a]));
                        }
                        let m = feature.constrained_directions(&mut dirs);
                        let m = tl.constrain(&mut cons, a, &dirs[..m], &mut held);
                        let x = reference[a] + u[a];
                        particular[a] += held[..m]
                            .iter()
                            .fold(Vector3::zeros(), |s, d| s + d * d.dot(&(target - x)));
                    }
                }
            }
            work.time.contact += contact_start.elapsed();
            let pi = &cons.projector;

            // 2. Right-hand side −Π (f + J u_p) and the linear solve Π J Π δ = rhs.
            let pmax = max_abs(&particular);
            let umax = max_abs(&u);
            if pmax > 0.0 {
                let h = 1e-7 * (1.0 + umax) / pmax;
                up.par_iter_mut()
                    .zip(u.par_iter())
                    .zip(particular.par_iter())
                    .for_each(|((w, a), b)| *w = a + b * h);
                if let Err(inv) = forces(model, &up, &mut ws, &mut fd, &mut work) {
                    return Err(inverted(iteration, inv));
                }
                rhs.par_iter_mut().zip(f.par_iter()).zip(fd.par_iter()).for_each(
                    |((r, f0), f1)| {
                        *r = -(f0 + (f1 - f0) / h);
                    },
                );
            } else {
                rhs.par_iter_mut().zip(f.par_iter()).for_each(|(r, f0)| *r = -f0);
            }
            pi.apply(&mut rhs);
            {
                let u_ref = &u;
                let f_ref = &f;
                let springs_ref = &springs;
                let mut op = |v: &[Vector3<f64>], out: &mut [Vector3<f64>]| {
                    let vmax = max_abs(v);
                    if vmax == 0.0 {
                        out.iter_mut().for_each(|o| *o = Vector3::zeros());
                        return;
                    }
                    let h = 1e-7 * (1.0 + umax) / vmax;
                    up.par_iter_mut()
                        .zip(u_ref.par_iter())
                        .zip(v.par_iter())
                        .for_each(|((w, a), b)| *w = a + b * h);
                    work.forces += 1;
                    let t = Instant::now();
                    let result = model.internal_forces_into(&up, &mut ws, out);
                    work.time.forces += t.elapsed();
                    match result {
                        Ok(()) => {
                            out.par_iter_mut()
                                .zip(f_ref.par_iter())
                                .for_each(|(o, f0)| *o = (*o - f0) / h);
                            for &(a, k) in springs_ref {
                                out[a] += v[a] * k;
                            }
                            pi.apply(out);
                        }
                        // A direction that inverts an element within h: treat as infinitely
                        // stiff (GMRES then leaves it alone).
                        Err(_) => out.iter_mut().zip(v).for_each(|(o, vi)| *o = vi * 1e30),
                    }
                };
                let mut prec_time = std::time::Duration::ZERO;
                let mut prec = |r: &[Vector3<f64>], z: &mut [Vector3<f64>]| {
                    let t = Instant::now();
                    tl.apply(&cons, r, z, &mut tl_scratch);
                    prec_time += t.elapsed();
                };
                // While prescribed displacement remains to be applied, the step carries it
                // into the mesh: solve it accurately, or the elements next to the prescribed
                // nodes take the whole jump and invert.
                // While the active set still moves (more than 1% of the contact nodes changed
                // state), the step only has to point the right way: the next linearisation
                // is about another set.
                let rtol = if applied < 1.0 {
                    p.forcing_min
                } else if changes as f64 > 0.01 * contact_nodes.len() as f64 {
                    p.forcing_active_set.max(eta)
                } else {
                    eta
                };
                let info = gmres.solve(
                    &mut op,
                    &mut prec,
                    &rhs,
                    &mut delta,
                    rtol,
                    p.max_linear_iterations,
                );
                work.linear += info.iterations;
                work.time.preconditioner += prec_time;
            }
            pi.apply(&mut delta);

            // 3. Line search on the natural residual.
            // Damp only the end game, when every change left is such a cycle (early on the
            // active set moves for good reasons and full steps are best).
            let mut alpha = if cycling > 0 && cycling == changes { 0.5 } else { 1.0f64 };
            let mut best: Option<(f64, f64)> = None; // (phi, alpha)
            let mut last_inversion = None;
            let accepted_phi;
            loop {
                trial_u
                    .par_iter_mut()
                    .zip(u.par_iter())
                    .zip(particular.par_iter().zip(delta.par_iter()))
                    .for_each(|((t, a), (pp, d))| *t = a + (pp + d) * alpha);
                match forces(model, &trial_u, &mut ws, &mut trial_f, &mut work) {
                    Err(inv) => last_inversion = Some(inv),
                    Ok(()) => {
                        let t = Instant::now();
                        let m = merit(
                            model,
                            &trial_u,
                            &trial_f,
                            &contact_nodes,
                            &is_contact,
                            gamma,
                            &fixed_pi,
                            contact,
                        )?;
                        work.time.contact += t.elapsed();
                        if iteration <= 1 || !phi.is_finite() || m <= (1.0 - 1e-4 * alpha) * phi {
                            accepted_phi = m;
                            break;
                        }
                        if best.is_none_or(|(b, _)| m < b) {
                            best = Some((m, alpha));
                        }
                    }
                }
                alpha *= 0.5;
                if alpha < 1.0 / 16.0 {
                    match best {
                        // No decrease found: take the best trial (it breaks cycles between
                        // surface features) and let the next linearisation correct it.
                        Some((m, a)) => {
                            alpha = a;
                            trial_u
                                .par_iter_mut()
                                .zip(u.par_iter())
                                .zip(particular.par_iter().zip(delta.par_iter()))
                                .for_each(|((t, b), (pp, d))| *t = b + (pp + d) * alpha);
                            if let Err(inv) =
                                forces(model, &trial_u, &mut ws, &mut trial_f, &mut work)
                            {
                                return Err(inverted(iteration, inv));
                            }
                            accepted_phi = m;
                            break;
                        }
                        None if alpha < 1.0 / 1024.0 => {
                            return Err(inverted(
                                iteration,
                                last_inversion.expect("an inverted trial"),
                            ));
                        }
                        None => {}
                    }
                }
            }
            // Accept.
            err =
                (0..n).into_par_iter().map(|a| (trial_u[a] - u[a]).amax()).reduce(|| 0.0, f64::max);
            std::mem::swap(&mut u, &mut trial_u);
            std::mem::swap(&mut f, &mut trial_f);
            applied = if alpha == 1.0 { 1.0 } else { applied + alpha * (1.0 - applied) };
            remaining.par_iter_mut().for_each(|r| *r *= 1.0 - alpha);
            if applied == 1.0 {
                remaining.iter_mut().for_each(|r| *r = Vector3::zeros());
            }
            let phi_prev = if phi.is_finite() { phi } else { accepted_phi };
            phi = accepted_phi;
            // Eisenstat–Walker (choice 2) forcing for the next linear solve, but no tighter
            // than the tolerance needs: a correction of about `err` solved to a relative
            // residual 0.1 tol/err errs by about a tenth of the tolerance.
            let ew = 0.9 * (phi / phi_prev).powi(2);
            let enough = if err > 0.0 { 0.1 * tol / err } else { 0.0 };
            eta = ew.max(enough).clamp(p.forcing_min, p.forcing_max);

            // 4. Guards and progress.
            let maxu = u.iter().fold(0.0f64, |m, v| m.max(v.norm()));
            if !(maxu.is_finite() && err.is_finite()) {
                return Err(SolveError::NotFinite { step: iteration });
            }
            if maxu > limit {
                return Err(SolveError::Diverged {
                    step: iteration,
                    max_displacement: maxu,
                    limit,
                });
            }
            let mut report = ContactReport::default();
            let t = Instant::now();
            for (k, &a) in contact_nodes.iter().enumerate() {
                positions[a] = reference[a] + u[a];
                if let Some(proj) = contact.project(k, &positions[a])
                    && proj.outside
                {
                    let d = (proj.point - positions[a]).norm();
                    report.max_penetration = report.max_penetration.max(d);
                }
                if !matches!(active[k], Active::Free) {
                    report.nodes_in_contact += 1;
                }
            }
            work.time.contact += t.elapsed();
            max_penetration = max_penetration.max(report.max_penetration);
            observer(&Progress {
                step: iteration,
                err,
                rho: 0.0,
                load_factor: applied,
                max_displacement: maxu,
                contact: report,
                linear_iterations: work.linear,
                force_evaluations: work.forces,
            });
            if err < tol && applied == 1.0 && changes == 0 && report.max_penetration < tol {
                // Kinematic contact on the answer (moves nodes outside by < tol).
                positions
                    .par_iter_mut()
                    .zip(reference.par_iter().zip(u.par_iter()))
                    .for_each(|(x, (x0, ua))| *x = x0 + ua);
                let last = contact.enforce(&mut positions);
                for &a in &contact_nodes {
                    u[a] = positions[a] - reference[a];
                }
                return Ok(Solution {
                    displacements: u,
                    report: Report {
                        solver: self.name(),
                        steps: iteration,
                        err,
                        tolerance: tol,
                        contact: ContactReport {
                            nodes_in_contact: report.nodes_in_contact.max(last.nodes_in_contact),
                            max_penetration: max_penetration.max(last.max_penetration),
                        },
                        force_evaluations: work.forces,
                        linear_iterations: work.linear,
                        breakdown: work.time,
                        elapsed: start.elapsed(),
                    },
                });
            }
            std::mem::swap(&mut before_previous, &mut previous);
            previous.copy_from_slice(&active);
        }
        Err(SolveError::NoConvergence { err, steps: p.max_iterations, tolerance: tol })
    }
}

fn inverted(step: usize, inv: Inversion) -> SolveError {
    SolveError::ElementInverted {
        step,
        element: inv.element,
        element_id: inv.element_id,
        jacobian: inv.jacobian,
    }
}

/// The Euclidean norm of the natural residual in length units: `γ_a Π r_a` at free nodes and
/// `x_a − Proj(x_a + γ_a Π r_a)` at contact nodes (`Π` removes fixed components). Newton
/// directions decrease this norm (it is the merit function of the line search).
#[allow(clippy::too_many_arguments)]
fn merit(
    model: &Model,
    u: &[Vector3<f64>],
    f: &[Vector3<f64>],
    contact_nodes: &[usize],
    is_contact: &[bool],
    gamma: &[f64],
    pi: &Projector,
    contact: &mut dyn Contact,
) -> Result<f64, SolveError> {
    let reference = model.reference();
    // Free nodes: the fixed components are projected out. Fixed-size chunks summed in order:
    // the same value for any thread count.
    let chunks: Vec<f64> = (0..u.len())
        .collect::<Vec<_>>()
        .par_chunks(2048)
        .map(|idx| {
            idx.iter()
                .filter(|&&a| !is_contact[a])
                .map(|&a| {
                    let r = if pi.constrained[a] { pi.matrix[a] * f[a] } else { f[a] };
                    (r * gamma[a]).norm_squared()
                })
                .sum::<f64>()
        })
        .collect();
    let mut m: f64 = chunks.iter().sum();
    for (k, &a) in contact_nodes.iter().enumerate() {
        let x = reference[a] + u[a];
        let y = x - pi.matrix[a] * f[a] * gamma[a];
        let proj = contact.project(k, &y).ok_or(SolveError::Unsupported {
            solver: "newton-krylov",
            what: "a contact handler that cannot project points",
            fix: "use a handler with exact projection, or the Dynamic Relaxation solver",
        })?;
        let target = if proj.outside { proj.point } else { y };
        m += (x - target).norm_squared();
    }
    Ok(m.sqrt())
}

impl Solver for NewtonKrylov {
    fn name(&self) -> &'static str {
        "newton-krylov"
    }

    fn solve(
        &self,
        model: &Model,
        loads: &Loads,
        contact: &mut dyn Contact,
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solution, SolveError> {
        let prep = self.prepare(model, loads)?;
        self.solve_prepared(model, loads, &prep, contact, observer)
    }
}
