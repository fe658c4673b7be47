//! One load level: the semismooth Newton iteration from the last converged state (or a
//! predictor from it) to equilibrium at the level's load, as calls on the named parts —
//! the active set, the schedule and load step, the linear solve, the forcing term, the
//! line search and the termination test.

use std::time::Instant;

use bs_mesh::Vector3;
use rayon::prelude::*;

use super::Work;
use super::active_set::SetChange;
use super::forcing::Forcing;
use super::iterate::Iterate;
use super::line_search::{self, Outcome};
use super::linear::forces;
use super::loading::{self, Schedule};
use super::merit::Merit;
use super::outcome::NewtonKrylovError;
use super::problem::Context;
use super::termination::{Failure, Iteration, Termination, Verdict};
use crate::contact::{Contact, ContactReport};
use crate::data::DataTerm;
use crate::solver::{LoadFailure, Progress};

/// Where a level starts.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Start<'a> {
    /// Load fraction of the last converged level, and the level's target.
    pub done: f64,
    pub target: f64,
    /// The converged state before the last and the predictor's factor, when there are two.
    pub secant: Option<(&'a [Vector3<f64>], f64)>,
}

/// How a load level ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Level {
    /// Converged at load fraction `reached` after `iterations` iterations.
    Converged { reached: f64, iterations: usize },
    /// Failed, and why.
    Failed { failure: LoadFailure },
    /// The solve's iteration budget ran out during the level.
    Exhausted,
}

/// Solves one level (see the module documentation).
pub(crate) fn solve(
    pb: &Context<'_>,
    it: &mut Iterate<'_>,
    work: &mut Work,
    start: Start<'_>,
    contact: &mut dyn Contact,
    data: &mut dyn DataTerm,
    observer: &mut dyn FnMut(&Progress),
) -> Result<Level, NewtonKrylovError> {
    let p = pb.params;
    let c = &p.continuation;
    let mut applied = start.done;
    let mut warm = false;
    if let Some((before, s)) = start.secant
        && let Some(t) =
            loading::predict(pb, it, work, before, s, start.done, start.target, contact)?
    {
        (applied, warm) = (t, true);
    }
    let target = start.target;
    let tol = if target < 1.0 { pb.tol * c.intermediate_tolerance } else { pb.tol };
    let mut schedule = Schedule::new(applied, target, c.equilibrium_iterations, 0.1);
    let mut term = Termination::new(tol, c.level_iterations, c.stall_iterations);
    let mut forcing = Forcing::new(p.forcing_min, p.forcing_max, p.forcing_active_set);
    let mut limiting = None;
    loop {
        if work.iterations >= p.max_iterations {
            return Ok(Level::Exhausted);
        }
        work.iterations += 1;
        // 0. The measurements linearised at the iterate (correspondences, robust weights):
        // the data force in `f` and the residual follow.
        // A data term linearised anew is a new problem: its residual starts a new descent, as
        // a load step's does (else the level would read the jump as a stall).
        let mut relinearised = false;
        if data.is_active() {
            let t = Instant::now();
            relinearised = it.relinearise(pb, data);
            it.phi = pb.merit(&it.u, &it.f, contact)?;
            work.time.contact += t.elapsed();
        }
        // 1. The active set: kept from the last level after a predictor, else chosen from the
        // trial points.
        let t = Instant::now();
        let change = if std::mem::take(&mut warm) {
            SetChange { changes: pb.nodes.len(), cycling: 0 }
        } else {
            it.active.choose(contact, &pb.nodes, &pb.node_state(&it.u, &it.f))?
        };
        work.time.contact += t.elapsed();
        // 2. The direction: a load step, or an equilibrium (Newton) step.
        let load = schedule.load_now(it.phi);
        let rtol = forcing.rtol(load, change.changes, pb.nodes.len());
        // The preconditioner rebuilt on the iterate once the elements have deformed enough
        // since it was built.
        let sub = if load {
            loading::load_step(pb, it, work, &schedule, rtol, contact)
        } else {
            loading::direction(pb, it, work, None, rtol).map(|()| target)
        }
        .map_err(NewtonKrylovError::inverted)?;
        // 3. The line search, its first trial capped by the elements.
        let first = if change.cycling > 0 && change.cycling == change.changes { 0.5 } else { 1.0 };
        let fraction = p.line_search.volume_fraction;
        let bound = pb.model.step_bound(&it.u, &it.direction, fraction, first);
        limiting = bound.element.or(limiting);
        let Some((alpha, merit)) = search(pb, it, work, bound.alpha, load, contact)? else {
            return Ok(Level::Failed { failure: would_invert(pb, limiting) });
        };
        // 4. Accept.
        if load {
            let reached = if alpha >= 1.0 {
                sub
            } else {
                schedule.applied + alpha * (sub - schedule.applied)
            };
            pb.apply_prescribed(reached.min(target), &mut it.trial_u);
            schedule.loaded(reached, merit);
        } else {
            schedule.equilibrated();
        }
        // With one level's budget left in the solve's, a level still loading ends at the load
        // it reached: the solve then ends at a converged fraction of the load.
        if schedule.loading() && p.max_iterations - work.iterations <= c.level_iterations {
            schedule.stop();
        }
        // The error estimate is the whole Newton correction, not the damped step taken.
        it.err = it.direction.par_iter().map(|d| d.amax()).reduce(|| 0.0, f64::max);
        std::mem::swap(&mut it.u, &mut it.trial_u);
        std::mem::swap(&mut it.f, &mut it.trial_f);
        let phi_prev = if it.phi.is_finite() { it.phi } else { merit };
        it.phi = merit;
        forcing.update(merit, phi_prev, it.err, pb.tol);
        // 5. Guards, progress and the verdict.
        let report = observe(pb, it, work, schedule.applied, contact, observer)?;
        let verdict = term.check(&Iteration {
            err: it.err,
            loading: schedule.loading(),
            loaded: load || relinearised,
            changes: change.changes,
            penetration: report.max_penetration,
            phi: it.phi,
        });
        it.active.settle();
        match verdict {
            Verdict::Continue => {}
            Verdict::Converged => {
                let iterations = term.iterations();
                return Ok(Level::Converged { reached: schedule.applied, iterations });
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

/// One jumping contact node (see [`line_search`]) allowed per this many contact nodes (at
/// least one).
const MAX_JUMPS_PER: usize = 1000;

/// The line search along `it.direction` from the first trial `first`; the trial taken is
/// left in `it.trial_u` / `it.trial_f`. `None` when no trial could be evaluated.
fn search(
    pb: &Context<'_>,
    it: &mut Iterate<'_>,
    work: &mut Work,
    first: f64,
    load: bool,
    contact: &mut dyn Contact,
) -> Result<Option<(f64, f64)>, NewtonKrylovError> {
    let phi = it.phi;
    let Iterate { u, trial_u, trial_f, ws, direction, data, .. } = it;
    let mut eval = |alpha: f64| -> Result<Option<Merit>, NewtonKrylovError> {
        trial_u
            .par_iter_mut()
            .zip(u.par_iter().zip(direction.par_iter()))
            .for_each(|(t, (a, d))| *t = a + d * alpha);
        if forces(pb.model, (data, pb.loads.forces()), trial_u, ws, trial_f, work).is_err() {
            return Ok(None);
        }
        let t = Instant::now();
        let m = pb.merit_split(trial_u, trial_f, contact, phi)?;
        work.time.contact += t.elapsed();
        Ok(Some(m))
    };
    let max_jumps = (pb.nodes.len() / MAX_JUMPS_PER).max(1);
    let p = &pb.params.line_search;
    let (outcome, last) = line_search::search(p, first, phi, load, max_jumps, &mut eval)?;
    if let Outcome::Best { alpha, .. } = outcome
        && alpha != last
    {
        // The trial held is not the one taken: evaluate it again.
        eval(alpha)?;
    }
    Ok(outcome.step())
}

fn would_invert(pb: &Context<'_>, element: Option<usize>) -> LoadFailure {
    match element {
        Some(e) => LoadFailure::WouldInvert { element: e, element_id: pb.model.element_ids()[e] },
        None => LoadFailure::Stalled { changes: 0 },
    }
}

/// Guards (not finite, diverged), the contact report of the iterate and the observer.
fn observe(
    pb: &Context<'_>,
    it: &mut Iterate<'_>,
    work: &mut Work,
    lambda: f64,
    contact: &mut dyn Contact,
    observer: &mut dyn FnMut(&Progress),
) -> Result<ContactReport, NewtonKrylovError> {
    let step = work.iterations;
    let maxu = it.u.par_iter().map(|v| v.norm()).reduce(|| 0.0, f64::max);
    if !(maxu.is_finite() && it.err.is_finite()) {
        return Err(NewtonKrylovError::NotFinite { step });
    }
    if maxu > pb.limit {
        return Err(NewtonKrylovError::Diverged { step, max_displacement: maxu, limit: pb.limit });
    }
    let reference = pb.model.reference();
    let mut report = ContactReport::default();
    let t = Instant::now();
    for (k, &a) in pb.nodes.iter().enumerate() {
        it.positions[a] = reference[a] + it.u[a];
        if let Some(proj) = contact.project(k, &it.positions[a])
            && proj.outside
        {
            report.max_penetration =
                report.max_penetration.max((proj.point - it.positions[a]).norm());
        }
    }
    work.time.contact += t.elapsed();
    report.nodes_in_contact = it.active.held();
    it.max_penetration = it.max_penetration.max(report.max_penetration);
    it.in_contact = report.nodes_in_contact;
    observer(&Progress {
        step,
        err: it.err,
        rho: 0.0,
        load_factor: lambda,
        max_displacement: maxu,
        contact: report,
        linear_iterations: work.linear,
        force_evaluations: work.forces,
    });
    Ok(report)
}
