//! The coarse levels of the hierarchy: their structure (prolongators between coarse levels,
//! product patterns, the coarsest level's symbolic factor), built once, and their numbers
//! ([`Levels`]) for one operator of level 1, made again whenever that operator changes (a
//! rebuild on the current configuration, a contact set).
//!
//! Level 1 holds the aggregates of the mesh, each a node of six unknowns; every level below
//! aggregates the centroids of the one above on a grid [`MultilevelParams::coarsening`]
//! times coarser, with the tentative prolongator of its modes smoothed once with its own
//! operator, until a level has at most [`MultilevelParams::coarsest`] unknowns or the
//! hierarchy [`MultilevelParams::max_levels`] levels: that level is solved exactly by a
//! sparse Cholesky factor (faer).

use bs_mesh::Point3;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::{Par, Side};
use nalgebra::SMatrix;
use rayon::prelude::*;
use std::sync::Arc;

use super::blocks::Blocks;
use super::params::{MultilevelError, MultilevelParams};
use super::products::{CoarseBlocks, LevelPatterns, coarse_times, smooth};
use super::tentative::{Aggregates, Matrix6, tentative};

/// A 6 × 6 block in single precision (the cycle's copies).
pub(crate) type Matrix6f = SMatrix<f32, 6, 6>;

/// The link from coarse level `l` to `l + 1`: its prolongator and product patterns.
#[derive(Debug)]
pub(crate) struct Link {
    pub(super) p: CoarseBlocks,
    pub(super) pt: CoarseBlocks,
    pub(super) p32: Blocks<f32, 6, 6>,
    pub(super) pt32: Blocks<f32, 6, 6>,
    pub(super) patterns: LevelPatterns,
}

/// The structure of the coarse levels, shared by every set of numbers.
#[derive(Debug)]
pub(crate) struct CoarseStructure {
    /// Level `l + 1` → `l + 2`.
    pub(super) links: Vec<Link>,
    /// Per coarse level (from level 1), per node, the unknowns its prolongator dropped.
    pub(super) dropped: Vec<Vec<[bool; 6]>>,
    /// The coarsest level's lower triangle, its scalar entries' sources and its symbolic
    /// Cholesky factor.
    coarsest: Coarsest,
}

/// The coarsest level as a scalar sparse matrix.
#[derive(Debug)]
struct Coarsest {
    pattern: SymbolicSparseColMat<usize>,
    /// Per scalar entry: (block position, row, column in the block).
    source: Vec<(u32, u8, u8)>,
    symbolic: Arc<SymbolicCholesky<usize>>,
}

/// One smoothed coarse level's numbers.
#[derive(Debug, Clone)]
pub(crate) struct Level {
    pub(super) a32: Blocks<f32, 6, 6>,
    pub(super) inv_diag: Vec<Matrix6f>,
    pub(super) lambda: f64,
}

/// The numbers of the coarse levels for one operator of level 1.
#[derive(Debug, Clone)]
pub(crate) struct Levels {
    /// Levels 1, 2, … above the coarsest (empty for a two-level method).
    pub(super) smoothed: Vec<Level>,
    /// The numeric Cholesky factor of the coarsest level.
    pub(super) factor: Vec<f64>,
    pub(super) symbolic: Arc<SymbolicCholesky<usize>>,
}

/// Power-method iterations for `λ_max` of a coarse level.
const POWER_ITERATIONS: usize = 15;

impl CoarseStructure {
    /// The coarse levels below level 1 (operator `a1`, nodes at `points`, modes `modes`, mesh
    /// aggregates of spacing `h`, `dropped` its unknowns dropped), and their numbers.
    pub(crate) fn new(
        a1: CoarseBlocks,
        points: Vec<Point3<f64>>,
        modes: Vec<Matrix6>,
        dropped: Vec<[bool; 6]>,
        h: f64,
        params: &MultilevelParams,
    ) -> Result<(Self, Levels), MultilevelError> {
        let mut links = Vec::new();
        let mut all_dropped = vec![dropped];
        let mut smoothed = Vec::new();
        let (mut a, mut points, mut modes, mut h) = (a1, points, modes, h);
        // Level 1 is level 2 of the hierarchy with the mesh.
        let mut level = 2;
        while 6 * a.rows() > params.coarsest && level < params.max_levels {
            h *= params.coarsening;
            let agg = Aggregates::new(&points, h);
            if agg.len() * 10 > a.rows() * 9 {
                break; // the grid no longer coarsens: solve this level
            }
            let drop = all_dropped.last().expect("level 1");
            let numbers = level_numbers(&a, drop);
            let (t, next) = tentative(&agg, &modes);
            let omega = 4.0 / (3.0 * numbers.lambda);
            let inv: Vec<Matrix6> = numbers.inv_diag.iter().map(|m| m.cast::<f64>()).collect();
            let p = smooth(&t, &coarse_times(&a, &t, agg.len()), &inv, omega);
            let pt = p.transpose(agg.len());
            let patterns = LevelPatterns::coarse(&a, &p, agg.len());
            let next_a = patterns.galerkin_coarse(&a, &p, &pt);
            all_dropped.push(next.iter().map(dropped_of).collect());
            let (p32, pt32) = (p.to_f32(), pt.to_f32());
            links.push(Link { p, pt, p32, pt32, patterns });
            smoothed.push(numbers);
            (a, points, modes) = (next_a, agg.centroid, next);
            level += 1;
        }
        let coarsest = Coarsest::new(&a)?;
        let drop = all_dropped.last().expect("a coarse level");
        let factor = coarsest.factorise(&a, drop)?;
        let levels = Levels { smoothed, factor, symbolic: coarsest.symbolic.clone() };
        Ok((CoarseStructure { links, dropped: all_dropped, coarsest }, levels))
    }

    /// The numbers of every coarse level for the level-1 operator `a1` (of the pattern the
    /// structure was built with).
    pub(crate) fn levels(&self, a1: CoarseBlocks) -> Result<Levels, MultilevelError> {
        let mut a = a1;
        let mut smoothed = Vec::with_capacity(self.links.len());
        for (l, link) in self.links.iter().enumerate() {
            smoothed.push(level_numbers(&a, &self.dropped[l]));
            a = link.patterns.galerkin_coarse(&a, &link.p, &link.pt);
        }
        let factor = self.coarsest.factorise(&a, self.dropped.last().expect("a level"))?;
        Ok(Levels { smoothed, factor, symbolic: self.coarsest.symbolic.clone() })
    }
}

/// The modes a node of the next level lost: zero rows of its `R`.
fn dropped_of(r: &Matrix6) -> [bool; 6] {
    std::array::from_fn(|k| r.row(k).iter().all(|&v| v == 0.0))
}

/// The block-diagonal inverses (dropped unknowns left out) and `λ_max(D⁻¹A)` of a level.
fn level_numbers(a: &CoarseBlocks, dropped: &[[bool; 6]]) -> Level {
    let n = a.rows();
    let inv_diag: Vec<Matrix6> = (0..n)
        .into_par_iter()
        .map(|i| {
            let (cols, vals) = a.row(i);
            let k = cols.binary_search(&(i as u32)).expect("diagonal block");
            pseudo_inverse(&vals[k], &dropped[i])
        })
        .collect();
    let lambda = 1.1 * power_max(a, &inv_diag);
    let a32 = a.to_f32();
    Level { a32, inv_diag: inv_diag.iter().map(|m| m.cast::<f32>()).collect(), lambda }
}

/// The inverse of `d` on the unknowns not dropped, zero on the dropped ones.
fn pseudo_inverse(d: &Matrix6, dropped: &[bool; 6]) -> Matrix6 {
    let keep = Matrix6::from_fn(|i, j| if i == j && !dropped[i] { 1.0 } else { 0.0 });
    let m = keep * d * keep + (Matrix6::identity() - keep);
    match m.try_inverse() {
        Some(inv) => keep * inv * keep,
        None => Matrix6::zeros(),
    }
}

/// `λ_max(D⁻¹ A)` by the power method (deterministic start).
fn power_max(a: &CoarseBlocks, inv_diag: &[Matrix6]) -> f64 {
    let n = a.rows();
    type V6 = SMatrix<f64, 6, 1>;
    let mut x: Vec<V6> = (0..n)
        .map(|i| V6::from_fn(|k, _| 1.0 + 0.5 * ((0.37 * (6 * i + k) as f64).sin())))
        .collect();
    let mut y = vec![V6::zeros(); n];
    let mut lambda = 0.0;
    for _ in 0..POWER_ITERATIONS {
        let m = x.iter().fold(0.0f64, |m, v| m.max(v.amax()));
        if m == 0.0 {
            return 1.0;
        }
        x.iter_mut().for_each(|v| *v /= m);
        y.par_iter_mut().enumerate().with_min_len(64).for_each(|(i, yi)| {
            let (cols, vals) = a.row(i);
            let mut acc = V6::zeros();
            for (&j, b) in cols.iter().zip(vals) {
                acc += b * x[j as usize];
            }
            *yi = inv_diag[i] * acc;
        });
        lambda = y.iter().fold(0.0f64, |m, v| m.max(v.amax()));
        std::mem::swap(&mut x, &mut y);
    }
    lambda
}

impl Coarsest {
    /// The scalar lower triangle of the block operator `a` and its symbolic factor.
    fn new(a: &CoarseBlocks) -> Result<Self, MultilevelError> {
        let n = a.rows();
        let mut col_ptr = vec![0usize];
        let mut row_idx = Vec::new();
        let mut source = Vec::new();
        for j in 0..n {
            let (cols, _) = a.row(j);
            let lo = a.ptr[j] as usize;
            for c in 0..6 {
                // Column 6j + c of the lower triangle: rows 6i + r ≥ 6j + c, i.e. the blocks
                // (i, j) with i ≥ j; by symmetry block (j, i) of row j, transposed.
                for (k, &i) in cols.iter().enumerate().filter(|(_, i)| **i as usize >= j) {
                    let first = if i as usize == j { c } else { 0 };
                    for r in first..6 {
                        row_idx.push(6 * i as usize + r);
                        // A_(6i+r, 6j+c) = block(j, i)[c, r].
                        source.push(((lo + k) as u32, c as u8, r as u8));
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        let pattern = SymbolicSparseColMat::new_checked(6 * n, 6 * n, col_ptr, None, row_idx);
        let symbolic = factorize_symbolic_cholesky(
            pattern.as_ref(),
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| MultilevelError::Factor(format!("{e:?}")))?;
        Ok(Coarsest { pattern, source, symbolic: Arc::new(symbolic) })
    }

    /// The numeric factor of `a` (its dropped unknowns given a unit diagonal).
    fn factorise(
        &self,
        a: &CoarseBlocks,
        dropped: &[[bool; 6]],
    ) -> Result<Vec<f64>, MultilevelError> {
        let mut val: Vec<f64> = self
            .source
            .iter()
            .map(|&(b, r, c)| a.val[b as usize][(r as usize, c as usize)])
            .collect();
        let (col_ptr, row_idx) = (self.pattern.col_ptr(), self.pattern.row_idx());
        for (i, d) in dropped.iter().enumerate() {
            for (k, &gone) in d.iter().enumerate() {
                if gone {
                    let q = 6 * i + k;
                    // The diagonal is the column's first entry.
                    debug_assert_eq!(row_idx[col_ptr[q]], q);
                    val[col_ptr[q]] += 1.0;
                }
            }
        }
        let matrix = SparseColMat::new(self.pattern.clone(), val);
        numeric(&self.symbolic, &matrix)
    }
}

/// The numeric Cholesky factor of `a` (lower triangle) on `symbolic`.
fn numeric(
    symbolic: &SymbolicCholesky<usize>,
    a: &SparseColMat<usize, f64>,
) -> Result<Vec<f64>, MultilevelError> {
    let mut values = vec![0.0; symbolic.len_val()];
    let mut mem = MemBuffer::try_new(
        symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
    )
    .map_err(|e| MultilevelError::Factor(format!("{e:?}")))?;
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
        .map_err(|_| MultilevelError::Singular)?;
    Ok(values)
}
