//! The fast steady-state solver: a semismooth Newton–Krylov method with the two-level
//! preconditioner of `K₀`, the kinematic contact linearised on its active set, load
//! continuation and a line search that never inverts an element.
//!
//! Each iteration solves the linearised equilibrium with GMRES ([`linear`]), applying the
//! Jacobian of the internal forces matrix-free (a forward difference of
//! [`Model::internal_forces_into`], so every element technology is linearised exactly as its
//! force kernel) and preconditioning with [`TwoLevel`], which depends only on mesh,
//! materials and fixed components and is prepared once ([`NewtonKrylov::prepare`]).
//!
//! # Contact
//!
//! The contact stays the paper's: frictionless, parameter-free, a node either inside the
//! cavity or on its surface. Its equilibrium conditions are written as the fixed point of the
//! projection that Dynamic Relaxation iterates, `x_a = Proj(x_a + γ_a r_a)` for every contact
//! node (`r_a` its out-of-balance force, `γ_a = 3 / tr K₀,aa` a nodal compliance): a node
//! whose trial point `x_a + γ_a r_a` lies inside is free; one whose trial point projects onto a
//! face is held on the face's plane and free along it; onto an edge, held on the edge's line;
//! onto a vertex, held at the vertex ([`active_set`]). This is the semismooth Newton method
//! for the natural residual of the contact conditions (the primal–dual active-set method
//! with the surface's non-smooth features): the active set and the feature of every contact
//! node are re-chosen every iteration from the current forces, so contact opens and closes,
//! and nodes slide over edges, without any penalty parameter.
//!
//! # Globalisation
//!
//! * Load continuation ([`continuation`]): the prescribed displacements are applied in
//!   increments of the load fraction λ, each level solved before the next (intermediate
//!   levels to a looser tolerance); an easy load is one increment. A level that fails is
//!   retried from the last converged state with a quarter of the increment; levels after
//!   the first start from a secant predictor through the last two converged states.
//! * The first Newton step of a level applies its prescribed displacement through the
//!   linearised system (the prescribed components move, the others follow the linear
//!   response). Every step, and the predictor, is capped so that no element's volume ratio
//!   falls below [`LineSearchParams::volume_fraction`] of its current value (exact per
//!   element, [`Model::step_bound`]); a load step so capped stops the level short, where the
//!   capped step took it.
//! * A backtracking line search on the natural residual ([`merit`], [`line_search`]).
//! * Inexact linear solves with Eisenstat–Walker forcing ([`forcing`]).
//!
//! # Termination
//!
//! A level is done when the last correction `max|Δu|` is below its tolerance with its
//! prescribed displacement applied, the active set and features unchanged and no node
//! outside ([`termination`]); with the iteration converging superlinearly the error of the
//! answer is a fraction of that last correction, which is reported as the error estimate.
//! Finally [`Contact::enforce`] moves any node still outside (by less than the tolerance)
//! onto the surface, as Dynamic Relaxation's last step would. A load the continuation cannot
//! carry stops with [`SolveError::LoadNotCarried`], naming the fraction reached and why.

mod active_set;
mod continuation;
mod forcing;
mod line_search;
mod linear;
mod merit;
mod params;
mod termination;

use std::time::Instant;

use bs_mesh::{Point3, Vector3};
use rayon::prelude::*;

use self::active_set::{ActiveSet, NodeState, SetChange};
use self::continuation::Continuation;
use self::forcing::Forcing;
use self::linear::{LinearBuffers, Linearisation, forces};
use self::termination::{Failure, Iteration, Termination, Verdict};
use crate::contact::{Contact, ContactReport};
use crate::assembly::{Inversion, Workspace};
use crate::linalg::krylov::Gmres;
use crate::loads::Loads;
use crate::model::Model;
use crate::solver::{
    Breakdown, LoadFailure, Progress, Report, Solution, SolveError, Solver, load_scale,
};
use crate::linalg::twolevel::{Constraints, Projector, TwoLevel};

pub use self::params::{ContinuationParams, LineSearchParams, NewtonKrylovParams};

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
pub(crate) struct Work {
    pub forces: usize,
    pub linear: usize,
    pub iterations: usize,
    pub time: Breakdown,
}

/// What a solve reads and does not change.
struct Problem<'a> {
    model: &'a Model,
    loads: &'a Loads,
    tl: &'a TwoLevel,
    gamma: &'a [f64],
    fixed: Projector,
    nodes: Vec<usize>,
    is_contact: Vec<bool>,
    tol: f64,
    limit: f64,
}

impl Problem<'_> {
    /// The prescribed value of component `k` of node `a` at load fraction `lambda`.
    fn prescribed(&self, lambda: f64, a: usize, k: usize) -> f64 {
        lambda * self.loads.value(a, k)
    }

    /// Sets the prescribed components of `u` to their values at `lambda`.
    fn apply_prescribed(&self, lambda: f64, u: &mut [Vector3<f64>]) {
        for (a, ua) in u.iter_mut().enumerate() {
            for k in 0..3 {
                if self.loads.is_constrained(a, k) {
                    ua[k] = self.prescribed(lambda, a, k);
                }
            }
        }
    }

    /// The prescribed displacement still to apply at `lambda`, into `out` (zero elsewhere).
    fn remaining(&self, lambda: f64, u: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        for (a, (o, ua)) in out.iter_mut().zip(u).enumerate() {
            *o = Vector3::from_fn(|k, _| {
                if self.loads.is_constrained(a, k) {
                    self.prescribed(lambda, a, k) - ua[k]
                } else {
                    0.0
                }
            });
        }
    }

    fn node_state<'s>(&'s self, u: &'s [Vector3<f64>], f: &'s [Vector3<f64>]) -> NodeState<'s> {
        NodeState {
            reference: self.model.reference(),
            u,
            f,
            fixed: &self.fixed,
            gamma: self.gamma,
        }
    }
}

/// The iterate and the buffers of a solve (allocated once).
struct Iterate {
    u: Vec<Vector3<f64>>,
    f: Vec<Vector3<f64>>,
    trial_u: Vec<Vector3<f64>>,
    trial_f: Vec<Vector3<f64>>,
    delta: Vec<Vector3<f64>>,
    particular: Vec<Vector3<f64>>,
    direction: Vec<Vector3<f64>>,
    springs: Vec<(usize, f64)>,
    positions: Vec<Point3<f64>>,
    active: ActiveSet,
    cons: Constraints,
    ws: Workspace,
    linear: LinearBuffers,
    /// The residual of `u` (∞ before it is known).
    phi: f64,
    max_penetration: f64,
    in_contact: usize,
}

/// The last converged levels: the state to return to after a failure and the two the
/// predictor extrapolates.
struct Converged {
    u: Vec<Vector3<f64>>,
    f: Vec<Vector3<f64>>,
    active: ActiveSet,
    phi: f64,
    before: Option<Vec<Vector3<f64>>>,
}

/// How a load level ended.
enum Level {
    /// Converged at load fraction `reached` after `iterations` iterations.
    Converged { reached: f64, iterations: usize },
    /// Failed: why, and the element that limited the last step, if one did.
    Failed { failure: LoadFailure },
}

impl NewtonKrylov {
    /// A solver with the given parameters.
    pub fn new(params: NewtonKrylovParams) -> Self {
        NewtonKrylov { params }
    }

    /// Builds the preconditioner for `model` with the prescribed components of `loads` (their
    /// values are not used).
    pub fn prepare(&self, model: &Model, loads: &Loads) -> Result<Preparation, SolveError> {
        self.params.validate()?;
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

    fn problem<'a>(
        &'a self,
        model: &'a Model,
        loads: &'a Loads,
        prep: &'a Preparation,
        contact: &dyn Contact,
    ) -> Result<Problem<'a>, SolveError> {
        self.params.validate()?;
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
        let nodes: Vec<usize> = contact.nodes().to_vec();
        if nodes.iter().any(|&a| a >= n) {
            return Err(SolveError::Unsupported {
                solver: "newton-krylov",
                what: "contact on a node outside the mesh",
                fix: "give the contact indices of mesh nodes",
            });
        }
        let mut is_contact = vec![false; n];
        for &a in &nodes {
            is_contact[a] = true;
        }
        let scale = load_scale(model, loads);
        Ok(Problem {
            model,
            loads,
            tl: &prep.preconditioner,
            gamma: &prep.compliance,
            fixed: prep.preconditioner.constraints().projector,
            nodes,
            is_contact,
            tol: self.params.tolerance * scale,
            limit: self.params.divergence_factor * scale,
        })
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
        let start = Instant::now();
        let pb = self.problem(model, loads, prep, contact)?;
        let n = model.node_count();
        let zeros = vec![Vector3::<f64>::zeros(); n];
        let mut work = Work::default();
        let mut it = Iterate {
            u: zeros.clone(),
            f: zeros.clone(),
            trial_u: zeros.clone(),
            trial_f: zeros.clone(),
            delta: zeros.clone(),
            particular: zeros.clone(),
            direction: zeros.clone(),
            springs: Vec::new(),
            positions: model.reference().to_vec(),
            active: ActiveSet::new(pb.nodes.len()),
            cons: pb.tl.constraints(),
            ws: model.workspace(),
            linear: LinearBuffers {
                up: zeros.clone(),
                fd: zeros.clone(),
                rhs: zeros,
                gmres: Gmres::new(n, self.params.restart),
                tl: pb.tl.scratch(),
            },
            phi: f64::INFINITY,
            max_penetration: 0.0,
            in_contact: 0,
        };
        if let Err(inv) = forces(model, &it.u, &mut it.ws, &mut it.f, &mut work) {
            return Err(inverted(0, inv));
        }
        let mut saved = Converged {
            u: it.u.clone(),
            f: it.f.clone(),
            active: it.active.clone(),
            phi: f64::INFINITY,
            before: None,
        };
        let mut cont = Continuation::new(self.params.continuation);
        let mut err = f64::INFINITY;
        while !cont.finished() {
            let target = cont.target();
            let outcome = self.level(
                &pb,
                &mut it,
                &mut work,
                (&cont, saved.before.as_deref()),
                target,
                contact,
                observer,
                &mut err,
            )?;
            match outcome {
                Level::Converged { reached, iterations } => {
                    cont.accept(reached, iterations);
                    let before = std::mem::replace(&mut saved.u, it.u.clone());
                    saved.before = Some(before);
                    saved.f.copy_from_slice(&it.f);
                    saved.active = it.active.clone();
                    saved.phi = it.phi;
                }
                Level::Failed { failure } => {
                    it.u.copy_from_slice(&saved.u);
                    it.f.copy_from_slice(&saved.f);
                    it.active = saved.active.clone();
                    it.phi = saved.phi;
                    if let Err(e) = cont.cut_back() {
                        return Err(SolveError::LoadNotCarried {
                            reached: e.reached,
                            load: load_scale(model, loads),
                            cause: failure,
                        });
                    }
                }
            }
        }
        Ok(self.finish(&pb, it, work, err, contact, start))
    }

    /// One load level: from the last converged state (and a predictor when there is one) to
    /// equilibrium at `target`.
    #[allow(clippy::too_many_arguments)]
    fn level(
        &self,
        pb: &Problem<'_>,
        it: &mut Iterate,
        work: &mut Work,
        (cont, before): (&Continuation, Option<&[Vector3<f64>]>),
        target: f64,
        contact: &mut dyn Contact,
        observer: &mut dyn FnMut(&Progress),
        err: &mut f64,
    ) -> Result<Level, SolveError> {
        let p = self.params;
        let done = cont.done();
        let mut target = target;
        // The load fraction applied so far at this level: the prescribed components of `u`
        // are at their values for it.
        let mut applied = done;
        let mut warm = false;
        if let (Some(s), Some(before)) = (cont.extrapolation(target), before) {
            if let Some(t) = self.predict(pb, it, work, before, s, done, target, contact)? {
                applied = t;
                warm = true;
            }
        }
        let mut loading = applied < target;
        // Between load steps, equilibrium iterations at the load applied so far, until the
        // residual left by the load step has fallen tenfold (or three of them).
        let mut since_load = usize::MAX;
        let mut phi_load = f64::INFINITY;
        let equilibrate = std::env::var("BS_EQUIL").ok().and_then(|v| v.parse::<usize>().ok()).unwrap_or(0);
        let level_tol = |target: f64| {
            if target < 1.0 { pb.tol * p.continuation.intermediate_tolerance } else { pb.tol }
        };
        let mut term = Termination::new(
            level_tol(target),
            p.continuation.level_iterations,
            p.continuation.stall_iterations,
        );
        let mut forcing = Forcing::new(p.forcing_min, p.forcing_max, p.forcing_active_set);
        let mut limiting: Option<usize> = None;
        loop {
            if work.iterations >= p.max_iterations {
                return Err(SolveError::NoConvergence {
                    err: *err,
                    steps: p.max_iterations,
                    tolerance: pb.tol,
                });
            }
            work.iterations += 1;
            let iteration = work.iterations;
            loading = applied < target
                && (since_load >= equilibrate
                    || it.phi <= 0.1 * phi_load);
            // 1. Active set: kept from the last level after a predictor, else chosen from the
            // trial points.
            let t = Instant::now();
            let change = if std::mem::take(&mut warm) {
                SetChange { changes: pb.nodes.len(), cycling: 0 }
            } else {
                it.active.choose(contact, &pb.nodes, &pb.node_state(&it.u, &it.f))?
            };
            work.time.contact += t.elapsed();
            // 2. The Newton direction (a load step while prescribed displacement remains).
            let accurate = loading && (applied == done || std::env::var("BS_LOAD_ACCURATE").is_ok());
            let rtol = forcing.rtol(accurate, change.changes, pb.nodes.len());
            let sub = if loading {
                self.load_step(pb, it, work, applied, target, rtol, contact)
            } else {
                self.direction(pb, it, work, None, rtol).map(|_| target)
            }
            .map_err(|inv| inverted(iteration, inv))?;
            // 3. Line search, its first trial capped by the elements.
            let first = if change.cycling > 0 && change.cycling == change.changes { 0.5 } else { 1.0 };
            let bound =
                pb.model.step_bound(&it.u, &it.direction, std::env::var("BS_VF").ok().and_then(|v| v.parse().ok()).unwrap_or(p.line_search.volume_fraction), first);
            if bound.element.is_some() {
                limiting = bound.element;
            }
            let (outcome, last) = {
                let phi = it.phi;
                let Iterate { u, trial_u, trial_f, ws, direction, .. } = &mut *it;
                let mut eval = |alpha: f64| -> Result<Option<f64>, SolveError> {
                    trial_u
                        .par_iter_mut()
                        .zip(u.par_iter().zip(direction.par_iter()))
                        .for_each(|(t, (a, d))| *t = a + d * alpha);
                    if forces(pb.model, trial_u, ws, trial_f, work).is_err() {
                        return Ok(None);
                    }
                    let t = Instant::now();
                    let m = merit::natural_residual(
                        pb.model,
                        trial_u,
                        trial_f,
                        &pb.nodes,
                        &pb.is_contact,
                        pb.gamma,
                        &pb.fixed,
                        contact,
                    )?;
                    work.time.contact += t.elapsed();
                    Ok(Some(m))
                };
                let r = line_search::search(&p.line_search, bound.alpha, phi, loading, &mut eval)?;
                if let Some((alpha, _)) = r.0.step()
                    && alpha != r.1
                {
                    // The trial held is not the one taken: evaluate it again.
                    eval(alpha)?;
                }
                r
            };
            let _ = last;
            let Some((alpha, merit)) = outcome.step() else {
                return Ok(Level::Failed { failure: would_invert(pb, limiting) });
            };
            // 4. Accept. A load step applies its share of the load.
            let load_step = loading;
            if loading {
                applied = if alpha >= 1.0 { sub } else { applied + alpha * (sub - applied) };
                pb.apply_prescribed(applied, &mut it.trial_u);
                loading = applied < target;
                since_load = 0;
                phi_load = merit;
            }
            if !load_step {
                since_load = since_load.saturating_add(1);
            }
            // The error estimate is the whole Newton correction, not the damped step taken.
            *err = it.direction.par_iter().map(|d| d.amax()).reduce(|| 0.0, f64::max);
            std::mem::swap(&mut it.u, &mut it.trial_u);
            std::mem::swap(&mut it.f, &mut it.trial_f);
            let phi_prev = if it.phi.is_finite() { it.phi } else { merit };
            it.phi = merit;
            forcing.update(merit, phi_prev, *err, pb.tol);
            // 5. Guards and progress.
            let report =
                self.observe(pb, it, work, iteration, *err, done, applied, contact, observer)?;
            if std::env::var("BS_NK_TRACE").is_ok() {
                eprintln!(
                    "it {iteration:3} lvl {applied:.4} alpha {alpha:.4} bound {:.4} err {:.3e} phi {:.3e} changes {} cycling {} held {} lin {} f {} pen {:.2e}",
                    bound.alpha, *err, it.phi, change.changes, change.cycling, report.nodes_in_contact, work.linear, work.forces, report.max_penetration
                );
            }
            if std::env::var("BS_NK_DUMP").is_ok() {
                self.dump(pb, it, contact);
            }
            let verdict = term.check(&Iteration {
                err: *err,
                loading,
                loaded: load_step,
                changes: change.changes,
                penetration: report.max_penetration,
                phi: it.phi,
            });
            it.active.settle();
            match verdict {
                Verdict::Continue => {}
                Verdict::Converged => {
                    return Ok(Level::Converged { reached: target, iterations: term.iterations() });
                }
                Verdict::Failed(f) => {
                    let failure = match (f, limiting) {
                        (_, Some(_)) => would_invert(pb, limiting),
                        (Failure::Stalled, None) => LoadFailure::Stalled { changes: change.changes },
                        (Failure::Budget, None) => {
                            LoadFailure::Budget { iterations: term.iterations() }
                        }
                    };
                    return Ok(Level::Failed { failure });
                }
            }
        }
    }

    /// The Newton direction: constraints and particular displacement from the active set
    /// (plus, while loading to `lambda`, the prescribed values still to apply), then the
    /// linear solve.
    fn direction(
        &self,
        pb: &Problem<'_>,
        it: &mut Iterate,
        work: &mut Work,
        loading: Option<f64>,
        rtol: f64,
    ) -> Result<(), Inversion> {
        match loading {
            Some(lambda) => pb.remaining(lambda, &it.u, &mut it.particular),
            None => it.particular.iter_mut().for_each(|v| *v = Vector3::zeros()),
        }
        it.active.constrain(
            pb.tl,
            &mut it.cons,
            &pb.nodes,
            &pb.node_state(&it.u, &it.f),
            &mut it.particular,
            &mut it.springs,
        );
        let lin = Linearisation {
            model: pb.model,
            u: &it.u,
            f: &it.f,
            particular: &it.particular,
            springs: &it.springs,
            cons: &it.cons,
            tl: pb.tl,
        };
        let info = linear::solve(
            &lin,
            &mut it.linear,
            &mut it.ws,
            &mut it.delta,
            rtol,
            self.params.max_linear_iterations,
            work,
        )?;
        if std::env::var("BS_NK_TRACE").is_ok() {
            eprintln!(
                "    solve rtol {rtol:.1e} gmres {} rel {:.2e} held {}",
                info.iterations,
                info.relative_residual,
                it.active.held()
            );
        }
        it.direction
            .par_iter_mut()
            .zip(it.particular.par_iter().zip(it.delta.par_iter()))
            .for_each(|(d, (pp, dd))| *d = pp + dd);
        Ok(())
    }

    /// A load step from `applied` towards `target`: the Newton direction that applies the
    /// remaining prescribed displacement, scaled down to the largest share of it the
    /// elements take (no volume ratio below the line search's fraction of its value), then,
    /// with contact, solved again with the free contact nodes that share would carry outside
    /// held where it takes them (so the step lands them on the surface instead of beyond
    /// it). Returns the load fraction the step aims at.
    #[allow(clippy::too_many_arguments)]
    fn load_step(
        &self,
        pb: &Problem<'_>,
        it: &mut Iterate,
        work: &mut Work,
        applied: f64,
        target: f64,
        rtol: f64,
        contact: &mut dyn Contact,
    ) -> Result<f64, Inversion> {
        self.direction(pb, it, work, Some(target), rtol)?;
        let fraction = std::env::var("BS_VF").ok().and_then(|v| v.parse().ok()).unwrap_or(self.params.line_search.volume_fraction);
        let cap = pb.model.step_bound(&it.u, &it.direction, fraction, 1.0).alpha;
        let sub = if cap < 1.0 { applied + cap * (target - applied) } else { target };
        if cap < 1.0 {
            it.direction.par_iter_mut().for_each(|d| *d *= cap);
        }
        if pb.nodes.is_empty() {
            return Ok(sub);
        }
        let reference = pb.model.reference();
        let t = Instant::now();
        let added = it.active.hold_predicted(contact, &pb.nodes, |a| {
            reference[a] + it.u[a] + it.direction[a]
        });
        work.time.contact += t.elapsed();
        if added > 0 {
            self.direction(pb, it, work, Some(sub), rtol)?;
        }
        Ok(sub)
    }

    /// The secant predictor `u + s (u − u_before)`, capped so that no element's volume ratio
    /// falls below the line search's fraction (the level's target shrinks with it), with
    /// the prescribed components set to their values at the (new) target. Returns the
    /// target, or `None` (and the state unchanged) when the prescribed values themselves
    /// invert an element: the level then starts with a load step.
    #[allow(clippy::too_many_arguments)]
    fn predict(
        &self,
        pb: &Problem<'_>,
        it: &mut Iterate,
        work: &mut Work,
        before: &[Vector3<f64>],
        s: f64,
        done: f64,
        target: f64,
        contact: &mut dyn Contact,
    ) -> Result<Option<f64>, SolveError> {
        it.direction
            .par_iter_mut()
            .zip(it.u.par_iter().zip(before.par_iter()))
            .for_each(|(d, (u, b))| *d = (u - b) * s);
        let bound =
            pb.model.step_bound(&it.u, &it.direction, self.params.line_search.volume_fraction, 1.0);
        let target = done + bound.alpha * (target - done);
        let alpha = bound.alpha;
        it.trial_u
            .par_iter_mut()
            .zip(it.u.par_iter().zip(it.direction.par_iter()))
            .for_each(|(t, (u, d))| *t = u + d * alpha);
        pb.apply_prescribed(target, &mut it.trial_u);
        // Predicted contact nodes outside go onto the surface, as the kinematic contact puts
        // them; nodes in contact at the last level stay held, on the feature where they are
        // now.
        let reference = pb.model.reference();
        let t = Instant::now();
        let trial = &mut it.trial_u;
        it.active.keep(contact, &pb.nodes, |a, p: Option<Point3<f64>>| match p {
            Some(p) => {
                trial[a] = p - reference[a];
                reference[a] + trial[a]
            }
            None => reference[a] + trial[a],
        });
        work.time.contact += t.elapsed();
        if forces(pb.model, &it.trial_u, &mut it.ws, &mut it.trial_f, work).is_err() {
            return Ok(None);
        }
        std::mem::swap(&mut it.u, &mut it.trial_u);
        std::mem::swap(&mut it.f, &mut it.trial_f);
        let t = Instant::now();
        it.phi = merit::natural_residual(
            pb.model,
            &it.u,
            &it.f,
            &pb.nodes,
            &pb.is_contact,
            pb.gamma,
            &pb.fixed,
            contact,
        )?;
        work.time.contact += t.elapsed();
        Ok(Some(target))
    }

    fn dump(&self, pb: &Problem<'_>, it: &Iterate, contact: &mut dyn Contact) {
        let reference = pb.model.reference();
        let mut rows: Vec<(f64, String)> = Vec::new();
        for a in 0..it.u.len() {
            if pb.is_contact[a] {
                continue;
            }
            let r = pb.fixed.matrix[a] * it.f[a];
            rows.push(((r * pb.gamma[a]).norm(), format!("free node {a} |r| {:.3e}", r.norm())));
        }
        for (k, &a) in pb.nodes.iter().enumerate() {
            let x = reference[a] + it.u[a];
            let y = x - pb.fixed.matrix[a] * it.f[a] * pb.gamma[a];
            let proj = contact.project(k, &y).unwrap();
            let target = if proj.outside { proj.point } else { y };
            let px = contact.project(k, &x).unwrap();
            rows.push((
                (x - target).norm(),
                format!(
                    "contact node {a} state {:?} proj_y {:?} outside {} x_outside {} dist_x {:.3e} |y-x| {:.3e}",
                    it.active.active[k], proj.feature, proj.outside, px.outside, (px.point - x).norm(), (y - x).norm()
                ),
            ));
        }
        rows.sort_by(|a, b| b.0.partial_cmp(&a.0).unwrap());
        for (v, s) in rows.iter().take(6) {
            eprintln!("   {v:.3e} {s}");
        }
    }

    /// Guards (not finite, diverged), the contact report of the iterate and the observer.
    #[allow(clippy::too_many_arguments)]
    fn observe(
        &self,
        pb: &Problem<'_>,
        it: &mut Iterate,
        work: &Work,
        iteration: usize,
        err: f64,
        _done: f64,
        lambda: f64,
        contact: &mut dyn Contact,
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<ContactReport, SolveError> {
        let maxu = it.u.iter().fold(0.0f64, |m, v| m.max(v.norm()));
        if !(maxu.is_finite() && err.is_finite()) {
            return Err(SolveError::NotFinite { step: iteration });
        }
        if maxu > pb.limit {
            return Err(SolveError::Diverged {
                step: iteration,
                max_displacement: maxu,
                limit: pb.limit,
            });
        }
        let reference = pb.model.reference();
        let mut report = ContactReport::default();
        let t = Instant::now();
        for (k, &a) in pb.nodes.iter().enumerate() {
            it.positions[a] = reference[a] + it.u[a];
            if let Some(proj) = contact.project(k, &it.positions[a])
                && proj.outside
            {
                let d = (proj.point - it.positions[a]).norm();
                report.max_penetration = report.max_penetration.max(d);
            }
        }
        report.nodes_in_contact = it.active.held();
        let _ = work;
        it.max_penetration = it.max_penetration.max(report.max_penetration);
        it.in_contact = report.nodes_in_contact;
        let elapsed = t.elapsed();
        observer(&Progress {
            step: iteration,
            err,
            rho: 0.0,
            load_factor: lambda,
            max_displacement: maxu,
            contact: report,
            linear_iterations: work.linear,
            force_evaluations: work.forces,
        });
        let _ = elapsed;
        Ok(report)
    }

    /// The kinematic contact on the converged answer (moves nodes outside by less than the
    /// tolerance onto the surface) and the report.
    fn finish(
        &self,
        pb: &Problem<'_>,
        mut it: Iterate,
        work: Work,
        err: f64,
        contact: &mut dyn Contact,
        start: Instant,
    ) -> Solution {
        let reference = pb.model.reference();
        it.positions
            .par_iter_mut()
            .zip(reference.par_iter().zip(it.u.par_iter()))
            .for_each(|(x, (x0, ua))| *x = x0 + ua);
        let last = contact.enforce(&mut it.positions);
        for &a in &pb.nodes {
            it.u[a] = it.positions[a] - reference[a];
        }
        Solution {
            displacements: it.u,
            report: Report {
                solver: self.name(),
                steps: work.iterations,
                err,
                tolerance: pb.tol,
                contact: ContactReport {
                    nodes_in_contact: it.in_contact.max(last.nodes_in_contact),
                    max_penetration: it.max_penetration.max(last.max_penetration),
                },
                force_evaluations: work.forces,
                linear_iterations: work.linear,
                breakdown: work.time,
                elapsed: start.elapsed(),
            },
        }
    }
}

fn would_invert(pb: &Problem<'_>, element: Option<usize>) -> LoadFailure {
    match element {
        Some(e) => LoadFailure::WouldInvert { element: e, element_id: pb.model.element_ids()[e] },
        None => LoadFailure::Stalled { changes: 0 },
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
