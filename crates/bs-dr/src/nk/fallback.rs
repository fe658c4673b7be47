//! The fallback of the continuation: when a load level has failed `max_cutbacks` times,
//! Dynamic Relaxation takes the last converged state and ramps the prescribed displacements
//! from there to their final values (its explicit steps are small and its contact is the
//! paper's projection). If it converges, that is the answer; if it stops too, its error goes
//! into the report of the load that could not be carried — and only then may the error say
//! the mesh cannot carry it (two different methods failed at the same place).

use bs_mesh::Vector3;

use super::problem::Context;
use crate::dr::{DrError, DrInfo, DrParams, DynamicRelaxation};
use crate::solver::{Progress, Solution};

/// The share of the scene's tolerance Dynamic Relaxation runs to when it takes over. Its
/// stopping test is an error estimate (the last correction over the Rayleigh quotient's
/// convergence rate), and the answer is then checked like any against the force balance the
/// tolerance allows: on the MNI152 brain at ν = 0.4999 (κ/μ 5000), where DR carries the push
/// after Newton–Krylov's budget, a fallback run to the tolerance itself ended at 1.278e-3 of
/// the largest reaction against a bound of about 1.28e-3 and was refused. Half of it keeps a
/// margin for a few more steps (DR converges linearly).
pub(crate) const FALLBACK_MARGIN: f64 = 0.5;

/// Runs Dynamic Relaxation from `start` (converged at load fraction `done`) to the full
/// load. Progress is reported after the Newton iterations already taken (`offset`), with
/// the load fraction of the whole path.
pub(crate) fn dynamic_relaxation(
    pb: &Context<'_>,
    start: &[Vector3<f64>],
    done: f64,
    offset: usize,
    (contact, data, observer): super::Seams<'_, '_, '_>,
) -> Result<Solution<DrInfo>, DrError> {
    let tolerance = FALLBACK_MARGIN * pb.params.tolerance;
    let dr = DynamicRelaxation::new(DrParams {
        tolerance,
        tolerance_unit: pb.params.tolerance_unit,
        ..DrParams::default()
    });
    let mut relay = |p: &Progress| {
        observer(&Progress {
            step: offset + p.step,
            load_factor: done + p.load_factor * (1.0 - done),
            ..*p
        })
    };
    dr.solve(crate::solver::Problem {
        model: pb.model,
        loads: pb.loads,
        start: Some(crate::solver::WarmStart { state: start, secant: None }),
        contact,
        data,
        observer: &mut relay,
        watch: None,
    })
}
