//! The coarse matrix of the constrained operator `Π K₀ Π` as a correction of the setup's
//! `Pᵀ K₀ P`: with `E = (Π − I) P`, nonzero only on the rows of the nodes the constraints
//! hold beyond the fixed components,
//!
//! `(P + E)ᵀ K₀ (P + E) = Pᵀ K₀ P + X + Xᵀ + Eᵀ K₀ E`,  `X = Eᵀ (K₀ P)`,
//!
//! a sum over the held nodes' rows of `E`, `K₀ P` and `K₀ E` only. Every term couples
//! coarse columns of aggregates that share a stiffness entry, inside the pattern of
//! `Pᵀ K₀ P`, so the setup's symbolic factor serves: a correction costs the local sums and
//! a numeric factorisation (on the MNI152 demo about 10 ms against 35 ms for the whole
//! Galerkin product, its ordering and symbolic factor).

use std::sync::Arc;

use faer::sparse::SparseColMat;
use faer::sparse::linalg::cholesky::SymbolicCholesky;

use super::coarse::{Coarse, numeric};
use super::params::TwoLevelError;
use super::rows::NodeRows;

/// The factor of `(P + E)ᵀ K₀ (P + E)` from the setup's `base` (`Pᵀ K₀ P`, lower
/// triangle) and the `symbolic` factor of its pattern; `e` holds `E` (empty rows at the
/// nodes not held), `kp` is `K₀ P`, `ke` is `K₀ E`.
pub(super) fn corrected(
    base: &SparseColMat<usize, f64>,
    symbolic: &Arc<SymbolicCholesky<usize>>,
    e: &NodeRows,
    kp: &NodeRows,
    ke: &NodeRows,
) -> Result<Coarse, TwoLevelError> {
    let mut a = base.clone();
    for h in 0..e.rows() {
        let (ecols, evals) = e.row(h);
        if ecols.is_empty() {
            continue;
        }
        // X_ij = E_hi · (K₀P)_hj enters the lower triangle at (max, min), twice on the
        // diagonal (X + Xᵀ); (Eᵀ K₀ E)_ij = E_hi · (K₀E)_hj is symmetric: its lower half.
        let (kcols, kvals) = kp.row(h);
        let (kecols, kevals) = ke.row(h);
        for (&i, ei) in ecols.iter().zip(evals) {
            for (&j, kj) in kcols.iter().zip(kvals) {
                let x = ei.dot(kj);
                add(&mut a, i.max(j), i.min(j), if i == j { 2.0 * x } else { x })?;
            }
            for (&j, kj) in kecols.iter().zip(kevals) {
                if j <= i {
                    add(&mut a, i, j, ei.dot(kj))?;
                }
            }
        }
    }
    numeric(symbolic.clone(), &a)
}

/// `a[row, col] += v` for an entry of `a`'s pattern (lower triangle: `row ≥ col`).
fn add(a: &mut SparseColMat<usize, f64>, row: u32, col: u32, v: f64) -> Result<(), TwoLevelError> {
    let (row, col) = (row as usize, col as usize);
    let range = a.symbolic().col_range(col);
    let k = a.symbolic().row_idx()[range.clone()].binary_search(&row).map_err(|_| {
        TwoLevelError::Factor(format!("coarse entry ({row}, {col}) outside the setup's pattern"))
    })?;
    a.val_mut()[range.start + k] += v;
    Ok(())
}
