//! How the load of a level goes in: the schedule (a load step, then equilibrium iterations
//! at the load applied so far until the residual the step left has fallen tenfold, then the
//! next load step), the load step itself and the secant predictor that starts a level from
//! the last two converged ones.
//!
//! A load step is the Newton direction that applies the remaining prescribed displacement,
//! scaled to the largest share of it the elements take (no volume ratio below the line
//! search's fraction of its value, [`Model::step_bound`](crate::Model::step_bound)); with
//! contact it is solved again with the free contact nodes that this share would carry
//! outside held where it takes them, so that the step lands them on the surface instead of
//! millimetres beyond it (the linear response knows nothing of the skull).

use bs_mesh::Vector3;
use rayon::prelude::*;
use std::time::Instant;

use super::Work;
use super::iterate::Iterate;
use super::linear::{self, Linearisation, forces};
use super::outcome::NewtonKrylovError;
use super::problem::Context;
use crate::assembly::Inversion;
use crate::contact::Contact;

/// When a level applies load and when it equilibrates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Schedule {
    /// Load fraction applied so far (the prescribed components of the iterate are at their
    /// values for it) and the level's target.
    pub applied: f64,
    pub target: f64,
    since_load: usize,
    phi_load: f64,
    equilibrate: usize,
    reduction: f64,
}

impl Schedule {
    /// From `applied` to `target`, with at most `equilibrate` equilibrium iterations between
    /// load steps (fewer when the residual falls by `reduction`).
    pub(crate) fn new(applied: f64, target: f64, equilibrate: usize, reduction: f64) -> Self {
        Schedule {
            applied,
            target,
            since_load: usize::MAX,
            phi_load: f64::INFINITY,
            equilibrate,
            reduction,
        }
    }

    /// Whether the next iteration is a load step, the residual of the iterate being `phi`.
    pub(crate) fn load_now(&self, phi: f64) -> bool {
        self.applied < self.target
            && (self.since_load >= self.equilibrate || phi <= self.reduction * self.phi_load)
    }

    /// Whether load remains to be applied.
    pub(crate) fn loading(&self) -> bool {
        self.applied < self.target
    }

    /// A load step reached `applied`, leaving the residual `phi`.
    pub(crate) fn loaded(&mut self, applied: f64, phi: f64) {
        self.applied = if applied >= self.target { self.target } else { applied };
        self.since_load = 0;
        self.phi_load = phi;
    }

    /// No more load at this level: it ends at the load applied so far.
    pub(crate) fn stop(&mut self) {
        self.target = self.applied;
    }

    /// An equilibrium iteration.
    pub(crate) fn equilibrated(&mut self) {
        self.since_load = self.since_load.saturating_add(1);
    }
}

/// The Newton direction into `it.direction`: constraints and particular displacement from
/// the active set (plus, while loading to `lambda`, the prescribed values still to apply),
/// then the linear solve to the relative residual `rtol`.
pub(crate) fn direction(
    pb: &Context<'_>,
    it: &mut Iterate<'_>,
    work: &mut Work,
    lambda: Option<f64>,
    rtol: f64,
) -> Result<(), Inversion> {
    match lambda {
        Some(l) => pb.remaining(l, &it.u, &mut it.particular),
        None => it.particular.iter_mut().for_each(|v| *v = Vector3::zeros()),
    }
    it.active.constrain(
        it.pre.get(),
        &mut it.cons,
        &pb.nodes,
        &pb.node_state(&it.u, &it.f),
        &mut it.particular,
        &mut it.springs,
    );
    // The preconditioner rebuilt on the iterate, its coarse levels for these constraints,
    // once the elements have deformed enough since it was built; else the coarse levels
    // for the contact constraints (see `Multilevel::constrain_coarse`).
    if it.pre.stale(pb.model, &it.u, pb.params.rebuild_strain)
        && it.pre.rebuild(pb.model, &it.u, &pb.fixed, &it.cons.projector, work)
    {
        it.cons = it.pre.get().constraints_like(&it.cons);
        it.linear.tl = it.pre.get().scratch();
    }
    let t = Instant::now();
    it.pre.get().constrain_coarse(&mut it.cons);
    work.time.preconditioner += t.elapsed();
    let lin = Linearisation {
        model: pb.model,
        data: &it.data,
        dead: pb.loads.forces(),
        u: &it.u,
        f: &it.f,
        particular: &it.particular,
        springs: &it.springs,
        cons: &it.cons,
        tl: it.pre.get(),
        load: None,
        stall_exit: pb.load == 0.0 && !pb.loads.forces().is_empty(),
    };
    let max = pb.params.max_linear_iterations;
    linear::solve(&lin, &mut it.linear, &mut it.ws, &mut it.delta, rtol, max, work)?;
    it.direction
        .par_iter_mut()
        .zip(it.particular.par_iter().zip(it.delta.par_iter()))
        .for_each(|(d, (pp, dd))| *d = pp + dd);
    Ok(())
}

/// A load step from `s.applied` towards `s.target` into `it.direction` (see the module
/// documentation). Returns the load fraction the step aims at.
pub(crate) fn load_step(
    pb: &Context<'_>,
    it: &mut Iterate<'_>,
    work: &mut Work,
    s: &Schedule,
    rtol: f64,
    contact: &mut dyn Contact,
) -> Result<f64, Inversion> {
    direction(pb, it, work, Some(s.target), rtol)?;
    let fraction = pb.params.line_search.volume_fraction;
    let cap = pb.model.step_bound(&it.u, &it.direction, fraction, 1.0).alpha;
    let sub = if cap < 1.0 { s.applied + cap * (s.target - s.applied) } else { s.target };
    if cap < 1.0 {
        it.direction.par_iter_mut().for_each(|d| *d *= cap);
    }
    if pb.nodes.is_empty() {
        return Ok(sub);
    }
    let reference = pb.model.reference();
    let t = Instant::now();
    let added =
        it.active.hold_predicted(contact, &pb.nodes, |a| reference[a] + it.u[a] + it.direction[a]);
    work.time.contact += t.elapsed();
    if added > 0 {
        direction(pb, it, work, Some(sub), rtol)?;
    }
    Ok(sub)
}

/// The secant predictor `u + s (u − u_before)` from the last converged state, capped so
/// that no element's volume ratio falls below the line search's fraction (the level's
/// target shrinks with it), the prescribed components at their values for the (new)
/// target, predicted contact nodes outside moved onto the surface and the last level's
/// contact nodes kept held. Returns the load fraction it reached, or `None` (the iterate
/// unchanged) when the predicted state inverts an element or would hold more new contact
/// nodes than were held (and more than 1 % of the contact nodes): the level then starts
/// with a load step.
///
/// The second refusal: the secant extrapolates one branch of the response, and where the
/// contact set more than doubles the prediction has crossed onto another. Holding every
/// node it pushes past the skull over-constrains the first iteration, and the release of
/// the surplus takes one Newton iteration per batch: at the MNI152 demo's contact onset
/// (the 4 mm update of `cargo xtask bench update`) 239 nodes held for 31 at equilibrium,
/// 9 Newton / 48 GMRES iterations; started with a load step instead, 6 / 38 (the coarse
/// ellipsoid's 6 mm update: 94 held for 47, 8 iterations, against 48 and 6).
#[allow(clippy::too_many_arguments)]
pub(crate) fn predict(
    pb: &Context<'_>,
    it: &mut Iterate<'_>,
    work: &mut Work,
    before: &[Vector3<f64>],
    s: f64,
    done: f64,
    target: f64,
    contact: &mut dyn Contact,
) -> Result<Option<f64>, NewtonKrylovError> {
    it.direction
        .par_iter_mut()
        .zip(it.u.par_iter().zip(before.par_iter()))
        .for_each(|(d, (u, b))| *d = (u - b) * s);
    let fraction = pb.params.line_search.volume_fraction;
    let alpha = pb.model.step_bound(&it.u, &it.direction, fraction, 1.0).alpha;
    let target = done + alpha * (target - done);
    it.trial_u
        .par_iter_mut()
        .zip(it.u.par_iter().zip(it.direction.par_iter()))
        .for_each(|(t, (u, d))| *t = u + d * alpha);
    pb.apply_prescribed(target, &mut it.trial_u);
    let reference = pb.model.reference();
    let t = Instant::now();
    let saved = it.active.clone();
    let held = saved.held();
    let trial = &mut it.trial_u;
    let added = it.active.keep(contact, &pb.nodes, |a, p| {
        if let Some(p) = p {
            trial[a] = p - reference[a];
        }
        reference[a] + trial[a]
    });
    work.time.contact += t.elapsed();
    // A few nodes touching (within 1 % of the contact nodes, the forcing's threshold of a
    // moving active set) is the secant's own branch ending, not a jump to another.
    if added > held.max(pb.nodes.len() / 100) {
        it.active = saved;
        return Ok(None);
    }
    if forces(
        pb.model,
        (&it.data, pb.loads.forces()),
        &it.trial_u,
        &mut it.ws,
        &mut it.trial_f,
        work,
    )
    .is_err()
    {
        it.active = saved;
        return Ok(None);
    }
    std::mem::swap(&mut it.u, &mut it.trial_u);
    std::mem::swap(&mut it.f, &mut it.trial_f);
    let t = Instant::now();
    it.phi = pb.merit(&it.u, &it.f, contact)?;
    work.time.contact += t.elapsed();
    Ok(Some(target))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_schedule_equilibrates_between_load_steps() {
        let mut s = Schedule::new(0.0, 1.0, 3, 0.1);
        assert!(s.load_now(f64::INFINITY)); // the first iteration loads
        s.loaded(0.4, 10.0);
        assert!(!s.load_now(5.0)); // the residual fell only twofold
        s.equilibrated();
        assert!(s.load_now(0.9)); // tenfold: the next load step
        s.equilibrated();
        s.equilibrated();
        s.equilibrated();
        assert!(s.load_now(9.0)); // or after three equilibrium iterations
        s.loaded(1.3, 1.0);
        assert_eq!(s.applied, 1.0); // never beyond the target
        assert!(!s.loading() && !s.load_now(0.0));
    }

    #[test]
    fn without_equilibrium_iterations_every_iteration_loads() {
        let mut s = Schedule::new(0.25, 1.0, 0, 0.1);
        s.loaded(0.5, 3.0);
        assert!(s.load_now(3.0));
    }
}
