//! The linear system of one Newton iteration on the free DOFs: the sparsity pattern of the
//! element tangents (lower triangle, duplicates summed by faer) and its symbolic Cholesky
//! factorisation, computed once; per iteration the assembled tangent, the residual as the
//! right-hand side (with `−K_fp Δu_p` when a load increment is applied) and the correction.

use bs_mesh::Vector3;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat};
use faer::{Mat, Side};

use super::outcome::NewtonError;
use crate::assembly::tangent::element_tangent;
use crate::loads::Loads;
use crate::model::Model;

/// The free-DOF tangent system of a model under given prescribed components.
pub(crate) struct TangentSystem {
    /// Free DOFs (`3 node + component`).
    pub free: Vec<usize>,
    /// Prescribed DOFs.
    pub fixed: Vec<usize>,
    /// DOF → row of the free system (`usize::MAX` for prescribed DOFs).
    dof_map: Vec<usize>,
    symbolic: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    llt: SymbolicLlt<usize>,
    values: Vec<f64>,
    /// One element tangent (up to 24×24).
    ke: Vec<f64>,
    /// The right-hand side, then the correction `δ` (one column).
    pub rhs: Mat<f64>,
}

impl TangentSystem {
    /// The pattern and symbolic factorisation for `model` with the prescribed DOFs of
    /// `loads`.
    pub(crate) fn new(model: &Model, loads: &Loads) -> Result<Self, NewtonError> {
        let singular = |_| NewtonError::SingularTangent { load_step: 0, iteration: 0 };
        let (free, fixed) = loads.split_dofs();
        let nf = free.len();
        let mut dof_map = vec![usize::MAX; 3 * model.node_count()];
        for (i, &d) in free.iter().enumerate() {
            dof_map[d] = i;
        }
        let mut pairs = Vec::new();
        for (_, e) in model.elements.iter() {
            for &na in e.nodes {
                for &nb in e.nodes {
                    for i in 0..3 {
                        for j in 0..3 {
                            let (r, c) =
                                (dof_map[3 * na as usize + i], dof_map[3 * nb as usize + j]);
                            if r != usize::MAX && c != usize::MAX && r >= c {
                                pairs.push(Pair { row: r, col: c });
                            }
                        }
                    }
                }
            }
        }
        let (symbolic, argsort) =
            SymbolicSparseColMat::<usize>::try_new_from_indices(nf, nf, &pairs)
                .map_err(|_| singular(()))?;
        let llt = SymbolicLlt::try_new(symbolic.as_ref(), Side::Lower).map_err(|_| singular(()))?;
        Ok(TangentSystem {
            free,
            fixed,
            dof_map,
            symbolic,
            argsort,
            llt,
            values: vec![0.0; pairs.len()],
            ke: vec![0.0; 24 * 24],
            rhs: Mat::<f64>::zeros(nf, 1),
        })
    }

    /// The Euclidean norm of `f` over the free DOFs.
    pub(crate) fn residual_norm(&self, f: &[Vector3<f64>]) -> f64 {
        self.free.iter().map(|&d| f[d / 3][d % 3].powi(2)).sum::<f64>().sqrt()
    }

    /// The largest component of the correction.
    pub(crate) fn max_correction(&self) -> f64 {
        (0..self.free.len()).fold(0.0f64, |a, i| a.max(self.rhs[(i, 0)].abs()))
    }

    /// The Newton correction at `u` with internal forces `forces` into [`rhs`](Self::rhs):
    /// `K δ = −f` on the free DOFs, minus `K_fp dp` when the increment `dp` of the
    /// prescribed DOFs is applied in this iteration. `(load_step, iteration)` name a
    /// failure.
    pub(crate) fn correction(
        &mut self,
        model: &Model,
        u: &[Vector3<f64>],
        forces: &[Vector3<f64>],
        dp: Option<&[f64]>,
        (load_step, iteration): (usize, usize),
    ) -> Result<(), NewtonError> {
        let singular = |_| NewtonError::SingularTangent { load_step, iteration };
        for (i, &d) in self.free.iter().enumerate() {
            self.rhs[(i, 0)] = -forces[d / 3][d % 3];
        }
        self.assemble(model, u, dp).map_err(singular)?;
        let kmat =
            SparseColMat::new_from_argsort(self.symbolic.clone(), &self.argsort, &self.values)
                .map_err(|_| singular(()))?;
        let llt = Llt::try_new_with_symbolic(self.llt.clone(), kmat.as_ref(), Side::Lower)
            .map_err(|_| singular(()))?;
        llt.solve_in_place(self.rhs.as_mut());
        Ok(())
    }

    /// The tangent's values in pattern order, and `−K_fp dp` added to the right-hand side;
    /// `Err` if an element is inverted.
    fn assemble(
        &mut self,
        model: &Model,
        u: &[Vector3<f64>],
        dp: Option<&[f64]>,
    ) -> Result<(), ()> {
        let mut pos = 0;
        for (_, e) in model.elements.iter() {
            let nn = e.len();
            let n3 = 3 * nn;
            let material = &model.elements.solids[e.mat].material;
            if !element_tangent(material, &e, u, &mut self.ke[..n3 * n3]) {
                return Err(());
            }
            for a in 0..nn {
                for b in 0..nn {
                    for i in 0..3 {
                        for j in 0..3 {
                            let gr = 3 * e.nodes[a] as usize + i;
                            let gc = 3 * e.nodes[b] as usize + j;
                            let (r, c) = (self.dof_map[gr], self.dof_map[gc]);
                            let v = self.ke[(3 * a + i) * n3 + 3 * b + j];
                            if r != usize::MAX && c != usize::MAX && r >= c {
                                self.values[pos] = v;
                                pos += 1;
                            }
                            if let Some(dp) = dp
                                && r != usize::MAX
                                && c == usize::MAX
                            {
                                self.rhs[(r, 0)] -= v * dp[gc];
                            }
                        }
                    }
                }
            }
        }
        debug_assert_eq!(pos, self.values.len());
        Ok(())
    }
}
