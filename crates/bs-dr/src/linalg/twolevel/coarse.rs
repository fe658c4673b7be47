//! The coarse space: geometric aggregates with their rigid-body modes (the tentative
//! prolongator) and the Galerkin coarse matrix `Pᵀ K₀ P`, factorised once.

use bs_mesh::{Point3, Vector3};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Par, Side};
use rayon::prelude::*;
use std::sync::Arc;

use super::params::TwoLevelError;
use super::projector::Projector;
use super::rows::{Accumulator, NodeRows};

/// The coarse factor.
#[derive(Debug)]
pub(crate) struct Coarse {
    /// Shared by every factor of the same pattern (the setup's and its corrections).
    pub(super) symbolic: Arc<SymbolicCholesky<usize>>,
    pub(super) values: Vec<f64>,
}

/// The setup's coarse matrix, assembled (lower triangle) and factorised.
#[derive(Debug)]
pub(crate) struct Galerkin {
    pub(crate) factor: Coarse,
    pub(crate) matrix: SparseColMat<usize, f64>,
}

/// Geometric aggregates of spacing `h` over the nodes at `x` and their rigid-body modes (the tentative
/// prolongator), masked by the fixed components and orthonormalised per aggregate.
pub(crate) fn tentative_prolongator(x: &[Point3<f64>], fixed: &Projector, h: f64) -> NodeRows {
    let n = x.len();
    let (mut lo, mut hi) = (x[0], x[0]);
    for p in x {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let dims: [usize; 3] = std::array::from_fn(|k| ((hi[k] - lo[k]) / h).floor() as usize + 1);
    let cell = |a: usize| -> usize {
        let idx: [usize; 3] =
            std::array::from_fn(|k| (((x[a][k] - lo[k]) / h) as usize).min(dims[k] - 1));
        (idx[2] * dims[1] + idx[1]) * dims[0] + idx[0]
    };
    let mut order: Vec<(usize, usize)> = (0..n).map(|a| (cell(a), a)).collect();
    order.sort_unstable();
    let mut rows: Vec<Vec<(u32, Vector3<f64>)>> = vec![Vec::new(); n];
    let mut column = 0u32;
    let mut start = 0;
    while start < order.len() {
        let mut end = start;
        while end < order.len() && order[end].0 == order[start].0 {
            end += 1;
        }
        let members: Vec<usize> = order[start..end].iter().map(|&(_, a)| a).collect();
        start = end;
        let centre =
            members.iter().fold(Vector3::zeros(), |s, &a| s + x[a].coords) / members.len() as f64;
        let mut basis: Vec<Vec<Vector3<f64>>> = Vec::new();
        for mode in 0..6 {
            let mut v: Vec<Vector3<f64>> = members
                .iter()
                .map(|&a| {
                    let r = x[a].coords - centre;
                    let m = match mode {
                        0 => Vector3::x(),
                        1 => Vector3::y(),
                        2 => Vector3::z(),
                        3 => Vector3::new(0.0, -r.z, r.y),
                        4 => Vector3::new(r.z, 0.0, -r.x),
                        _ => Vector3::new(-r.y, r.x, 0.0),
                    };
                    fixed.matrix[a] * m
                })
                .collect();
            let norm0 = v.iter().map(|w| w.norm_squared()).sum::<f64>().sqrt();
            for _ in 0..2 {
                for b in &basis {
                    let d: f64 = v.iter().zip(b).map(|(p, q)| p.dot(q)).sum();
                    v.iter_mut().zip(b).for_each(|(p, q)| *p -= q * d);
                }
            }
            let nv = v.iter().map(|w| w.norm_squared()).sum::<f64>().sqrt();
            if nv > 1e-6 * norm0 && nv > 0.0 {
                v.iter_mut().for_each(|w| *w /= nv);
                basis.push(v);
            }
        }
        for b in basis {
            for (&a, w) in members.iter().zip(b) {
                rows[a].push((column, w));
            }
            column += 1;
        }
    }
    NodeRows::from_rows(rows)
}

/// `A_c = Pᵀ (K₀ P)` assembled and factorised.
pub(crate) fn galerkin(pt: &NodeRows, kp: &NodeRows, nc: usize) -> Result<Galerkin, TwoLevelError> {
    let rows: Vec<Vec<(u32, f64)>> = (0..nc)
        .into_par_iter()
        .with_min_len(16)
        .map_init(
            || Accumulator::<f64>::new(nc),
            |acc, i| {
                let (nodes, vals) = pt.row(i);
                for (&a, pa) in nodes.iter().zip(vals) {
                    add_row(acc, i, pa, kp, a);
                }
                acc.drain()
            },
        )
        .collect();
    let mut triplets = Vec::with_capacity(rows.iter().map(Vec::len).sum());
    for (i, row) in rows.iter().enumerate() {
        triplets.extend(row.iter().map(|&(j, v)| Triplet::new(i, j as usize, v)));
    }
    let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(nc, nc, &triplets)
        .map_err(|e| TwoLevelError::Factor(format!("{e:?}")))?;
    let symbolic = factorize_symbolic_cholesky(
        matrix.symbolic(),
        Side::Lower,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams::default(),
    )
    .map_err(|e| TwoLevelError::Factor(format!("{e:?}")))?;
    let factor = numeric(Arc::new(symbolic), &matrix)?;
    Ok(Galerkin { factor, matrix })
}

/// `acc_j += p · (KP)_aj` for the columns `j ≤ i` of row `a` of `kp`.
#[inline]
fn add_row(acc: &mut Accumulator<f64>, i: usize, p: &Vector3<f64>, kp: &NodeRows, a: u32) {
    let (cols, kvals) = kp.row(a as usize);
    for (&j, kv) in cols.iter().zip(kvals) {
        if j as usize <= i {
            acc.add(j, p.dot(kv));
        }
    }
}

/// The numeric Cholesky factor of `a` (lower triangle) on the symbolic factor of its pattern.
pub(super) fn numeric(
    symbolic: Arc<SymbolicCholesky<usize>>,
    a: &SparseColMat<usize, f64>,
) -> Result<Coarse, TwoLevelError> {
    let mut values = vec![0.0; symbolic.len_val()];
    let mut mem = MemBuffer::try_new(
        symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
    )
    .map_err(|e| TwoLevelError::Factor(format!("{e:?}")))?;
    symbolic
        .factorize_numeric_llt(
            &mut values,
            a.as_ref(),
            Side::Lower,
            LltRegularization {
                dynamic_regularization_delta: 0.0,
                dynamic_regularization_epsilon: 0.0,
            },
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .map_err(|_| TwoLevelError::Singular)?;
    Ok(Coarse { symbolic, values })
}
