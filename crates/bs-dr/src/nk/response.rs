//! The linear response at a converged state: how the answer moves when the equations it
//! solves change a little (a measured point's noise, a load parameter), without another
//! nonlinear solve. At an equilibrium `r(u) = 0` a change `δr` of the residual moves the
//! answer by `δu = −J⁻¹ δr`, with `J` the tangent there: the elements' (forward
//! differences of their forces, as the Newton steps), the data springs' linearised at the
//! state, and the contact nodes held on their features as the state holds them (their
//! normal direction removed, as the fixed components are). Each response is one GMRES
//! solve with the state's preconditioner: the preconditioner and the active set are made
//! once, for any number of responses (an uncertainty's samples).

use bs_mesh::Vector3;

use super::Work;
use super::iterate::Iterate;
use super::linear::{self, Linearisation};
use super::outcome::NewtonKrylovError;
use super::problem::Context;
use super::{NewtonKrylov, Preparation};
use crate::contact::Contact;
use crate::data::DataTerm;
use crate::loads::Loads;
use crate::model::Model;

/// What one response solve did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResponseInfo {
    /// GMRES iterations.
    pub iterations: usize,
    /// The relative residual reached, and whether it reached the tolerance asked for.
    pub relative_residual: f64,
    pub converged: bool,
}

/// The tangent at a converged state, ready to give responses
/// ([`NewtonKrylov::with_response`]).
pub struct Response<'p, 'a> {
    pb: &'p Context<'a>,
    it: Iterate<'a>,
    work: Work,
}

impl std::fmt::Debug for Response<'_, '_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Response").field("iterations", &self.work.linear).finish_non_exhaustive()
    }
}

impl Response<'_, '_> {
    /// The response `out = δu` to the residual change `residual_change = δr` (nodal
    /// forces: the change of internal minus external forces at the state), to GMRES's
    /// relative residual `rtol`. Fixed components and held contact normals of `δr` are
    /// ignored and stay zero in `δu`.
    pub fn solve(
        &mut self,
        residual_change: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
        rtol: f64,
    ) -> Result<ResponseInfo, NewtonKrylovError> {
        let n = self.it.u.len();
        if residual_change.len() != n || out.len() != n {
            return Err(NewtonKrylovError::Unsupported {
                what: "a residual change or response of another length than the model's nodes",
                fix: "give one vector per node",
            });
        }
        let it = &mut self.it;
        it.delta.iter_mut().zip(residual_change).for_each(|(l, r)| *l = -r);
        let lin = Linearisation {
            model: self.pb.model,
            data: &it.data,
            dead: self.pb.loads.forces(),
            u: &it.u,
            f: &it.f,
            particular: &it.particular,
            springs: &it.springs,
            cons: &it.cons,
            tl: it.pre.get(),
            load: Some(&it.delta),
            stall_exit: false,
        };
        let max = self.pb.params.max_linear_iterations;
        let info = linear::solve(&lin, &mut it.linear, &mut it.ws, out, rtol, max, &mut self.work)
            .map_err(NewtonKrylovError::inverted)?;
        let (iterations, relative_residual) = (info.iterations, info.relative_residual);
        Ok(ResponseInfo { iterations, relative_residual, converged: info.converged })
    }

    /// GMRES iterations of every response so far.
    pub fn gmres_iterations(&self) -> usize {
        self.work.linear
    }
}

impl NewtonKrylov {
    /// Calls `f` with the tangent at the converged displacements `state` of `loads`
    /// (`data` linearised there, the contact's active set chosen there): see [`Response`].
    /// `prep` is the preparation the state was solved with.
    #[allow(clippy::too_many_arguments)]
    pub fn with_response<R>(
        &self,
        model: &Model,
        loads: &Loads,
        prep: &Preparation,
        state: &[Vector3<f64>],
        contact: &mut dyn Contact,
        data: &mut dyn DataTerm,
        f: impl FnOnce(&mut Response<'_, '_>) -> R,
    ) -> Result<R, NewtonKrylovError> {
        let pb = Context::new(&self.params, model, loads, prep, &*contact, Some(state))?;
        let mut work = Work::default();
        let mut it = Iterate::new(&pb, &mut work, data)?;
        it.active.choose(contact, &pb.nodes, &pb.node_state(&it.u, &it.f))?;
        it.active.constrain(
            it.pre.get(),
            &mut it.cons,
            &pb.nodes,
            &pb.node_state(&it.u, &it.f),
            &mut it.particular,
            &mut it.springs,
        );
        // The response moves from the state as it is: no particular displacement.
        it.particular.iter_mut().for_each(|p| *p = Vector3::zeros());
        if it.pre.stale(pb.model, &it.u, pb.params.rebuild_strain)
            && it.pre.rebuild(pb.model, &it.u, &pb.fixed, &it.cons.projector, &mut work)
        {
            it.cons = it.pre.get().constraints_like(&it.cons);
            it.linear.tl = it.pre.get().scratch();
        }
        it.pre.get().constrain_coarse(&mut it.cons);
        let mut response = Response { pb: &pb, it, work };
        Ok(f(&mut response))
    }
}
