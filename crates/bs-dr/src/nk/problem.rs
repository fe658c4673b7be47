//! What a solve reads and does not change: the model, the loads, the preparation, the
//! contact nodes, the tolerances; and the prescribed values along the continuation.

use bs_mesh::Vector3;

use super::merit::Merit;
use super::outcome::NewtonKrylovError;
use super::{NewtonKrylovParams, Preparation};
use crate::contact::Contact;
use crate::linalg::multilevel::{Multilevel, Projector};
use crate::loads::Loads;
use crate::model::Model;
use crate::solver::load_scale;

use super::active_set::NodeState;

/// The read-only side of a solve.
pub(crate) struct Context<'a> {
    pub model: &'a Model,
    pub loads: &'a Loads,
    /// The preparation's preconditioner (built at the reference state).
    pub base: &'a Multilevel,
    /// Nodal compliances `γ_a = 3 / tr K₀,aa`.
    pub gamma: &'a [f64],
    /// The fixed components' projector.
    pub fixed: Projector,
    /// The contact nodes, and which nodes they are.
    pub nodes: Vec<usize>,
    pub is_contact: Vec<bool>,
    pub params: &'a NewtonKrylovParams,
    /// Absolute tolerance and divergence bound (length units).
    pub tol: f64,
    pub limit: f64,
    /// The load's size: the largest prescribed value, or from a start state the largest
    /// change of a prescribed value.
    pub load: f64,
    /// The state the solve starts from (a converged state of other prescribed values), or
    /// `None` for the reference state.
    pub start: Option<&'a [Vector3<f64>]>,
}

impl<'a> Context<'a> {
    /// Checks that `loads`, `prep` and `contact` fit `model`.
    pub(crate) fn new(
        params: &'a NewtonKrylovParams,
        model: &'a Model,
        loads: &'a Loads,
        prep: &'a Preparation,
        contact: &dyn Contact,
        start: Option<&'a [Vector3<f64>]>,
    ) -> Result<Self, NewtonKrylovError> {
        params.validate()?;
        let n = model.node_count();
        if loads.node_count() != n {
            return Err(NewtonKrylovError::LoadMismatch { expected: n, got: loads.node_count() });
        }
        if let Some(s) = start
            && s.len() != n
        {
            return Err(NewtonKrylovError::Unsupported {
                what: "a start state with another number of nodes than the model",
                fix: "start from displacements of this model's nodes",
            });
        }
        if !prep.fits(loads) {
            return Err(NewtonKrylovError::Unsupported {
                what: "a preparation built for other prescribed components",
                fix: "prepare again with these loads",
            });
        }
        let nodes: Vec<usize> = contact.nodes().to_vec();
        if nodes.iter().any(|&a| a >= n) {
            return Err(NewtonKrylovError::Unsupported {
                what: "contact on a node outside the mesh",
                fix: "give the contact indices of mesh nodes",
            });
        }
        let mut is_contact = vec![false; n];
        for &a in &nodes {
            is_contact[a] = true;
        }
        let scale = load_scale(model, loads);
        Ok(Context {
            model,
            loads,
            base: &prep.preconditioner,
            gamma: &prep.compliance,
            fixed: prep.preconditioner.constraints().projector,
            nodes,
            is_contact,
            params,
            tol: params.tolerance_unit.length(params.tolerance, scale),
            limit: params.divergence_factor * scale,
            load: change(loads, start),
            start,
        })
    }

    /// The prescribed value of component `k` of node `a` at load fraction `lambda`: from
    /// the start state's value at 0 to the final one at 1 (from zero without a start state).
    fn prescribed(&self, lambda: f64, a: usize, k: usize) -> f64 {
        let end = self.loads.value(a, k);
        match self.start {
            Some(s) => s[a][k] + lambda * (end - s[a][k]),
            None => lambda * end,
        }
    }

    /// Sets the prescribed components of `u` to their values at `lambda`.
    pub(crate) fn apply_prescribed(&self, lambda: f64, u: &mut [Vector3<f64>]) {
        for (a, ua) in u.iter_mut().enumerate() {
            for k in 0..3 {
                if self.loads.is_constrained(a, k) {
                    ua[k] = self.prescribed(lambda, a, k);
                }
            }
        }
    }

    /// The prescribed displacement still to apply at `lambda`, into `out` (zero elsewhere).
    pub(crate) fn remaining(&self, lambda: f64, u: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
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

    /// The geometry the active set is chosen from.
    pub(crate) fn node_state<'s>(
        &'s self,
        u: &'s [Vector3<f64>],
        f: &'s [Vector3<f64>],
    ) -> NodeState<'s> {
        NodeState { reference: self.model.reference(), u, f, fixed: &self.fixed, gamma: self.gamma }
    }

    /// The natural residual of `(u, f)` (the line search's merit).
    pub(crate) fn merit(
        &self,
        u: &[Vector3<f64>],
        f: &[Vector3<f64>],
        contact: &mut dyn Contact,
    ) -> Result<f64, NewtonKrylovError> {
        self.merit_split(u, f, contact, f64::INFINITY).map(|m| m.value)
    }

    /// The natural residual of `(u, f)`, with the contact nodes whose own term exceeds
    /// `jump` counted apart ([`Merit`]).
    pub(crate) fn merit_split(
        &self,
        u: &[Vector3<f64>],
        f: &[Vector3<f64>],
        contact: &mut dyn Contact,
        jump: f64,
    ) -> Result<Merit, NewtonKrylovError> {
        super::merit::natural_residual(
            self.model,
            u,
            f,
            &self.nodes,
            &self.is_contact,
            self.gamma,
            &self.fixed,
            contact,
            jump,
        )
    }
}

/// The largest prescribed value of `loads`, or its largest change from `start`.
fn change(loads: &Loads, start: Option<&[Vector3<f64>]>) -> f64 {
    let Some(s) = start else { return loads.max_prescribed() };
    let mut m = 0.0f64;
    for (a, sa) in s.iter().enumerate() {
        for k in 0..3 {
            if loads.is_constrained(a, k) {
                m = m.max((loads.value(a, k) - sa[k]).abs());
            }
        }
    }
    m
}
