//! The coarse levels of a contact set as a local correction of the preconditioner's own.
//!
//! The own levels were built under the projectors `Π₀` (the fixed components, or a solve's
//! constraints at a rebuild) with the prolongator `P₀ = Π₀ P`; a contact set's are those of
//! `P₁ = Π₁ P`. With `E = P₁ − P₀ = (Π₁ − Π₀) P`, nonzero only on the rows of the nodes
//! whose constraints changed,
//!
//! `P₁ᵀ K P₁ = P₀ᵀ K P₀ + X + Xᵀ + Eᵀ K E`,  `X = Eᵀ (K P₀)`,
//!
//! a sum over the changed rows `h` of `E_h`, `(K P₀)_h` and `(K E)_h` only. `(K P₀)_h` comes
//! from the products the own levels kept (`E P₀` and `C P₀`), `(K E)_h` from the changed
//! neighbours of `h` and the nodal terms around them. Every term couples coarse columns of
//! aggregates that share a stiffness entry, inside the Galerkin pattern, so the levels below
//! and the coarsest symbolic factor serve; the correction costs the local sums, the levels
//! below and a numeric factor (on the MNI152 demo about a tenth of the whole product).

use nalgebra::Matrix3;
use rayon::prelude::*;
use std::sync::Arc;

use super::blocks::{NONE, mark, unmark};
use super::constraints::Built;
use super::params::MultilevelError;
use super::products::{CoarseBlocks, FineProducts, Row6};
use super::projector::Projector;
use super::setup::Multilevel;
use super::tentative::Matrix6;
use crate::linalg::nodal::NodalMatrix;

/// A 3 × 6 block.
type Block = nalgebra::SMatrix<f64, 3, 6>;

/// A sparse row of 3 × 6 blocks by coarse column, columns increasing.
type SparseRow = Vec<(u32, Block)>;

/// What one changed row contributes: `E_h`, `(K P₀)_h` and `(K E)_h`.
struct Changed {
    e: SparseRow,
    kp: SparseRow,
    ke: SparseRow,
}

impl Multilevel {
    /// The coarse levels of `k` under `pi`, corrected from the own levels' `products`.
    pub(super) fn corrected(
        &self,
        k: &NodalMatrix,
        products: &FineProducts,
        pi: &Projector,
    ) -> Result<Built, MultilevelError> {
        let st = &self.structure;
        let p0 = &self.levels.projector;
        let fixed = &self.fixed.projector;
        let n = st.p.rows();
        let nc = st.pt.rows();
        let changed: Vec<bool> = (0..n).into_par_iter().map(|a| pi.matrix[a] != p0[a]).collect();
        let rows: Vec<u32> = (0..n as u32).filter(|&a| changed[a as usize]).collect();
        let delta = |b: usize| -> Option<Matrix3<f64>> { changed[b].then(|| pi.matrix[b] - p0[b]) };
        let e_row = |b: usize| -> SparseRow {
            let d = delta(b).unwrap_or_else(Matrix3::zeros);
            let (cols, vals) = st.p.row(b);
            cols.iter().zip(vals).map(|(&j, v)| (j, d * v)).collect()
        };
        // `c_t E` for the terms with a changed node.
        let (qp, _) = st.fine.terms();
        let ce: Vec<Option<Vec<(u32, Row6)>>> = match &k.nodal {
            Some(c) => (0..c.terms())
                .into_par_iter()
                .with_min_len(256)
                .map_init(
                    || vec![NONE; nc],
                    |pos, t| {
                        let (lo, hi) = (c.c_ptr[t] as usize, c.c_ptr[t + 1] as usize);
                        if !c.c_col[lo..hi].iter().any(|&m| changed[m as usize]) {
                            return None;
                        }
                        let cols = qp.row(t);
                        mark(pos, cols);
                        let mut out = vec![Row6::zeros(); cols.len()];
                        for m in lo..hi {
                            let b = c.c_col[m] as usize;
                            if let Some(d) = delta(b) {
                                let cd = c.c_val[m].transpose() * d;
                                let (pc, pv) = st.p.row(b);
                                for (&j, v) in pc.iter().zip(pv) {
                                    out[pos[j as usize] as usize] += cd * v;
                                }
                            }
                        }
                        unmark(pos, cols);
                        Some(cols.iter().copied().zip(out).collect())
                    },
                )
                .collect(),
            None => Vec::new(),
        };
        let e = &k.assembled;
        let q_of = |t: usize| {
            let (lo, hi) = (qp.ptr[t] as usize, qp.ptr[t + 1] as usize);
            qp.col[lo..hi].iter().copied().zip(products.q[lo..hi].iter().copied())
        };
        let contributions: Vec<Changed> = rows
            .par_iter()
            .with_min_len(16)
            .map_init(
                || Accumulator::new(nc),
                |acc, &h| {
                    let h = h as usize;
                    // (K P₀)_h = (E P₀)_h + Σ_t c_th w_t (c_t P₀).
                    let (kc, kv) = products.ep.row(h);
                    kc.iter().zip(kv).for_each(|(&j, v)| acc.add(j, *v));
                    if let Some(c) = &k.nodal {
                        for m in c.t_ptr[h] as usize..c.t_ptr[h + 1] as usize {
                            let t = c.t_col[m] as usize;
                            let cw = c.t_val[m] * c.weight[t];
                            q_of(t).for_each(|(j, v)| acc.add(j, cw * v));
                        }
                    }
                    let kp = acc.drain();
                    // (K E)_h = Σ_b K_hb E_b + Σ_t c_th w_t (c_t E).
                    for s in e.ptr[h] as usize..e.ptr[h + 1] as usize {
                        let b = e.col[s] as usize;
                        if let Some(d) = delta(b) {
                            let kd = e.val[s] * d;
                            let (pc, pv) = st.p.row(b);
                            pc.iter().zip(pv).for_each(|(&j, v)| acc.add(j, kd * v));
                        }
                    }
                    if let Some(c) = &k.nodal {
                        for m in c.t_ptr[h] as usize..c.t_ptr[h + 1] as usize {
                            let t = c.t_col[m] as usize;
                            if let Some(row) = &ce[t] {
                                let cw = c.t_val[m] * c.weight[t];
                                row.iter().for_each(|&(j, v)| acc.add(j, cw * v));
                            }
                        }
                    }
                    let ke = acc.drain();
                    Changed { e: e_row(h), kp, ke }
                },
            )
            .collect();
        let mut a1 = products.a1.clone();
        add_corrections(&mut a1, &contributions)?;
        let levels = st.coarse.levels(a1)?;
        let held = (0..n).filter(|&a| pi.constrained[a] && pi.matrix[a] != fixed.matrix[a]).count();
        Ok(Built {
            levels: Arc::new(levels),
            fine: None,
            projector: Arc::new(pi.matrix.clone()),
            held,
        })
    }
}

/// `a += Σ_h E_hᵀ (K P₀)_h + its transpose + E_hᵀ (K E)_h`, in the order of the rows.
fn add_corrections(a: &mut CoarseBlocks, changed: &[Changed]) -> Result<(), MultilevelError> {
    for c in changed {
        for &(i, ei) in &c.e {
            let eit = ei.transpose();
            for &(j, kj) in &c.kp {
                let x: Matrix6 = eit * kj;
                *block(a, i, j)? += x;
                *block(a, j, i)? += x.transpose();
            }
            for &(j, kj) in &c.ke {
                *block(a, i, j)? += eit * kj;
            }
        }
    }
    Ok(())
}

/// Block `(i, j)` of `a`'s pattern.
fn block(a: &mut CoarseBlocks, i: u32, j: u32) -> Result<&mut Matrix6, MultilevelError> {
    let (lo, hi) = (a.ptr[i as usize] as usize, a.ptr[i as usize + 1] as usize);
    let k = a.col[lo..hi].binary_search(&j).map_err(|_| {
        MultilevelError::Factor(format!("coarse block ({i}, {j}) outside the Galerkin pattern"))
    })?;
    Ok(&mut a.val[lo + k])
}

/// A sparse accumulator of 3 × 6 blocks over the coarse columns.
struct Accumulator {
    val: Vec<Block>,
    mark: Vec<bool>,
    touched: Vec<u32>,
}

impl Accumulator {
    fn new(n: usize) -> Self {
        Accumulator { val: vec![Block::zeros(); n], mark: vec![false; n], touched: Vec::new() }
    }

    #[inline]
    fn add(&mut self, c: u32, v: Block) {
        let k = c as usize;
        if !self.mark[k] {
            self.mark[k] = true;
            self.val[k] = Block::zeros();
            self.touched.push(c);
        }
        self.val[k] += v;
    }

    /// The accumulated blocks in increasing column order; resets.
    fn drain(&mut self) -> SparseRow {
        self.touched.sort_unstable();
        let out = self.touched.iter().map(|&c| (c, self.val[c as usize])).collect();
        for &c in &self.touched {
            self.mark[c as usize] = false;
        }
        self.touched.clear();
        out
    }
}
