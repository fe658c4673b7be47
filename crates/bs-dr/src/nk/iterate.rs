//! The iterate of a solve and every buffer it needs, allocated once before the loop, and
//! the snapshots of the last converged levels (where a failed level returns to, and what
//! the predictor extrapolates).

use bs_mesh::{Point3, Vector3};

use super::Work;
use super::active_set::ActiveSet;
use super::linear::{LinearBuffers, forces};
use super::outcome::NewtonKrylovError;
use super::problem::Context;
use super::refresh::Following;
use crate::assembly::Workspace;
use crate::data::{DataTerm, Springs};
use crate::linalg::krylov::Gmres;
use crate::linalg::multilevel::Constraints;

/// The iterate and the buffers of a solve.
pub(crate) struct Iterate<'a> {
    pub u: Vec<Vector3<f64>>,
    /// Internal forces at `u`.
    pub f: Vec<Vector3<f64>>,
    pub trial_u: Vec<Vector3<f64>>,
    pub trial_f: Vec<Vector3<f64>>,
    /// GMRES's part of the direction, the particular part, and their sum.
    pub delta: Vec<Vector3<f64>>,
    pub particular: Vec<Vector3<f64>>,
    pub direction: Vec<Vector3<f64>>,
    pub springs: Vec<(usize, f64)>,
    /// The data term linearised at the last relinearisation (empty without measurements).
    pub data: Springs,
    pub positions: Vec<Point3<f64>>,
    pub active: ActiveSet,
    /// The preconditioner, following the state.
    pub pre: Following<'a>,
    pub cons: Constraints,
    pub ws: Workspace,
    pub linear: LinearBuffers,
    /// The natural residual of `u` (∞ before it is known).
    pub phi: f64,
    /// Largest penetration of any iterate, and nodes held at the last one.
    pub max_penetration: f64,
    pub in_contact: usize,
    /// The last correction (error estimate).
    pub err: f64,
}

impl<'a> Iterate<'a> {
    /// The start state (zero displacement without one), the data term linearised there,
    /// and its forces.
    pub(crate) fn new(
        pb: &Context<'a>,
        work: &mut Work,
        data: &mut dyn DataTerm,
    ) -> Result<Self, NewtonKrylovError> {
        let n = pb.model.node_count();
        let zeros = vec![Vector3::<f64>::zeros(); n];
        let mut it = Iterate {
            u: pb.start.map_or_else(|| zeros.clone(), <[Vector3<f64>]>::to_vec),
            f: zeros.clone(),
            trial_u: zeros.clone(),
            trial_f: zeros.clone(),
            delta: zeros.clone(),
            particular: zeros.clone(),
            direction: zeros.clone(),
            springs: Vec::new(),
            data: Springs::new(),
            positions: pb.model.reference().to_vec(),
            active: ActiveSet::new(pb.nodes.len()),
            pre: Following::new(pb.base, n),
            cons: pb.base.constraints(),
            ws: pb.model.workspace(),
            linear: LinearBuffers {
                up: zeros.clone(),
                fd: zeros.clone(),
                rhs: zeros,
                gmres: Gmres::new(n, pb.params.restart),
                tl: pb.base.scratch(),
                mixed: None,
            },
            phi: f64::INFINITY,
            max_penetration: 0.0,
            in_contact: 0,
            err: f64::INFINITY,
        };
        if data.is_active() {
            it.set_positions(pb);
            data.linearise(&it.positions, &mut it.data);
        }
        forces(pb.model, (&it.data, pb.loads.forces()), &it.u, &mut it.ws, &mut it.f, work)
            .map_err(NewtonKrylovError::inverted)?;
        Ok(it)
    }

    /// `positions ← X + u` for every node.
    pub(crate) fn set_positions(&mut self, pb: &Context<'_>) {
        let reference = pb.model.reference();
        self.positions.iter_mut().zip(reference.iter().zip(&self.u)).for_each(|(x, (x0, u))| {
            *x = x0 + u;
        });
    }

    /// The data term linearised again at the iterate: its forces in `f` move from the old
    /// springs to the new ones (no element work: the springs are linear in `u`). Returns
    /// whether the springs changed (the problem the iteration solves did).
    pub(crate) fn relinearise(&mut self, pb: &Context<'_>, data: &mut dyn DataTerm) -> bool {
        let reference = pb.model.reference();
        let old = self.data.clone();
        self.data.add_forces_into(reference, &self.u, -1.0, &mut self.f);
        self.set_positions(pb);
        data.linearise(&self.positions, &mut self.data);
        self.data.add_forces_into(reference, &self.u, 1.0, &mut self.f);
        old != self.data
    }
}

/// The last converged state, and the one before it.
pub(crate) struct Converged {
    u: Vec<Vector3<f64>>,
    f: Vec<Vector3<f64>>,
    /// The data springs `f` was computed with.
    data: Springs,
    active: ActiveSet,
    phi: f64,
    before: Option<Vec<Vector3<f64>>>,
}

impl Converged {
    /// The start state of a solve.
    pub(crate) fn start(it: &Iterate<'_>) -> Self {
        Converged {
            u: it.u.clone(),
            f: it.f.clone(),
            data: it.data.clone(),
            active: it.active.clone(),
            phi: it.phi,
            before: None,
        }
    }

    /// A level converged at `it`: it becomes the last state, the last one the one before.
    pub(crate) fn push(&mut self, it: &Iterate<'_>) {
        let before = std::mem::replace(&mut self.u, it.u.clone());
        self.before = Some(before);
        self.f.copy_from_slice(&it.f);
        self.data.clone_from(&it.data);
        self.active = it.active.clone();
        self.phi = it.phi;
    }

    /// A level failed: `it` goes back to the last converged state.
    pub(crate) fn restore(&self, it: &mut Iterate<'_>) {
        it.u.copy_from_slice(&self.u);
        it.f.copy_from_slice(&self.f);
        it.data.clone_from(&self.data);
        it.active = self.active.clone();
        it.phi = self.phi;
    }

    /// The converged state before the last, for the secant predictor.
    pub(crate) fn before(&self) -> Option<&[Vector3<f64>]> {
        self.before.as_deref()
    }

    /// The last converged displacements.
    pub(crate) fn displacements(&self) -> &[Vector3<f64>] {
        &self.u
    }
}
