//! The fallback of the continuation: when a load level has failed `max_cutbacks` times,
//! Dynamic Relaxation takes the last converged state and ramps the prescribed displacements
//! from there to their final values (its explicit steps are small and its contact is the
//! paper's projection). If it converges, that is the answer; if it stops too, its error goes
//! into the report of the load that could not be carried — and only then may the error say
//! the mesh cannot carry it (two different methods failed at the same place).

use bs_mesh::Vector3;

use super::problem::Problem;
use crate::contact::Contact;
use crate::dr::{DrError, DrInfo, DrParams, DynamicRelaxation};
use crate::solver::{Progress, Solution};

/// Runs Dynamic Relaxation from `start` (converged at load fraction `done`) to the full
/// load. Progress is reported after the Newton iterations already taken (`offset`), with
/// the load fraction of the whole path.
pub(crate) fn dynamic_relaxation(
    pb: &Problem<'_>,
    start: &[Vector3<f64>],
    done: f64,
    offset: usize,
    contact: &mut dyn Contact,
    observer: &mut dyn FnMut(&Progress),
) -> Result<Solution<DrInfo>, DrError> {
    let dr =
        DynamicRelaxation::new(DrParams { tolerance: pb.params.tolerance, ..DrParams::default() });
    let mut relay = |p: &Progress| {
        observer(&Progress {
            step: offset + p.step,
            load_factor: done + p.load_factor * (1.0 - done),
            ..*p
        })
    };
    dr.solve_from(pb.model, start, pb.loads, contact, &mut relay)
}
