//! The products of the hierarchy on patterns fixed once per prolongator, so that the coarse
//! operators of another operator of the same sparsity (the stiffness on the current
//! configuration, or the same stiffness under other contact constraints) cost the
//! arithmetic alone.
//!
//! On the mesh the operator is `K = E + Cᵀ W C` ([`NodalMatrix`]: 3 × 3 blocks and the
//! T4ANP rank-one nodal terms); below, a coarse operator of 6 × 6 blocks. For a prolongator
//! `P` (blocks of 6 columns, one block column per aggregate):
//!
//! * `A P` row by row (`E P + Cᵀ W (C P)` on the mesh);
//! * the Galerkin operator `Pᵀ A P` block row by block row, the lower blocks `J ≤ I` summed
//!   (`Σ_a P_aIᵀ (A P)_aJ`) and mirrored: on the mesh `Pᵀ E P + Σ_t w_t (c_t P)ᵀ (c_t P)`,
//!   the nodal terms as outer products of their rows `q_t = c_t P` (whose `E P`-like
//!   product would reach the two-ring).
//!
//! Every output row is summed by one task in a fixed order: the numbers do not depend on
//! the thread count.

use nalgebra::{SMatrix, Vector3};
use rayon::prelude::*;

use super::blocks::{Blocks, NONE, Pattern, mark, unmark};
use super::tentative::Matrix6;
use crate::linalg::nodal::NodalMatrix;
use crate::linalg::sparse::split_rows;

/// A prolongator from the mesh (3 rows per node).
pub(crate) type FineP = Blocks<f64, 3, 6>;
/// A prolongator between coarse levels, or a coarse operator.
pub(crate) type CoarseBlocks = Blocks<f64, 6, 6>;

/// `1 × 6` rows `q_t = c_t P` of the nodal terms.
pub(crate) type Row6 = SMatrix<f64, 1, 6>;

/// The Galerkin operator of the mesh's operator and the products it was summed from, kept
/// for the local corrections of a contact set (`super::correction`).
#[derive(Debug, Clone)]
pub(crate) struct FineProducts {
    /// `Pᵀ K P`, both triangles.
    pub(super) a1: CoarseBlocks,
    /// `E P` (the assembled part).
    pub(super) ep: FineP,
    /// `C P`, unweighted, on the terms' pattern (empty without nodal terms).
    pub(super) q: Vec<Row6>,
}

/// The pattern of a symmetric block operator with the position of every block's mirror.
#[derive(Debug, Clone)]
pub(crate) struct Symmetric {
    pub(super) pattern: Pattern,
    /// Per block `(I, J)`, the position of `(J, I)`.
    mirror: Vec<u32>,
}

impl Symmetric {
    /// The symmetric closure of `lower` (blocks `J ≤ I` per row `I`).
    fn new(lower: &Pattern) -> Self {
        let n = lower.rows();
        let pattern = Pattern::union(n, n, |i, add| {
            lower.row(i).iter().for_each(|&j| add(j));
        });
        // Add the transposes: every (I, J) of the lower part also as (J, I).
        let mut upper: Vec<Vec<u32>> = vec![Vec::new(); n];
        for i in 0..n {
            for &j in lower.row(i) {
                if (j as usize) < i {
                    upper[j as usize].push(i as u32);
                }
            }
        }
        let pattern = Pattern::union(n, n, |i, add| {
            pattern.row(i).iter().for_each(|&j| add(j));
            upper[i].iter().for_each(|&j| add(j));
        });
        let find = |i: usize, j: u32| -> u32 {
            let row = pattern.row(i);
            pattern.ptr[i] + row.binary_search(&j).expect("symmetric pattern") as u32
        };
        let mirror = (0..n)
            .flat_map(|i| pattern.row(i).iter().map(move |&j| (i, j)))
            .map(|(i, j)| find(j as usize, i as u32))
            .collect();
        Symmetric { pattern, mirror }
    }

    /// Copies every block above the diagonal from its mirror below.
    fn mirror_upper(&self, a: &mut CoarseBlocks) {
        let n = self.pattern.rows();
        let lower: Vec<Matrix6> = a.val.clone();
        let rows = a.rows_mut();
        rows.into_par_iter().enumerate().with_min_len(16).for_each(|(i, row)| {
            let lo = self.pattern.ptr[i] as usize;
            for (k, &j) in self.pattern.row(i).iter().enumerate() {
                if j as usize > i {
                    row[k] = lower[self.mirror[lo + k] as usize].transpose();
                }
            }
        });
        debug_assert_eq!(n, a.rows());
    }
}

/// The patterns of the products of one level, fixed for a prolongator.
#[derive(Debug, Clone)]
pub(crate) struct LevelPatterns {
    /// `A P` (on the mesh `E P`, the assembled part only).
    ap: Pattern,
    /// On the mesh: `C P`, one row per nodal term, and its transpose (aggregate → terms).
    q: Pattern,
    qt: Pattern,
    /// The Galerkin operator.
    pub(super) coarse: Symmetric,
}

/// The positions of a row being summed (a dense scratch of the column count).
fn positions(n: usize) -> Vec<u32> {
    vec![NONE; n]
}

impl LevelPatterns {
    /// The patterns of the mesh's products: `E` of `k` (with the nodal terms of `k`, if any)
    /// times `p` (`nc` block columns; transpose `pt`).
    pub(crate) fn fine(k: &NodalMatrix, p: &FineP, nc: usize) -> Self {
        let e = &k.assembled;
        let ap = Pattern::union(p.rows(), nc, |a, add| {
            for &b in &e.col[e.ptr[a] as usize..e.ptr[a + 1] as usize] {
                p.row(b as usize).0.iter().for_each(|&j| add(j));
            }
        });
        let (q, qt) = match &k.nodal {
            Some(c) => {
                let q = Pattern::union(c.terms(), nc, |t, add| {
                    for &m in &c.c_col[c.c_ptr[t] as usize..c.c_ptr[t + 1] as usize] {
                        p.row(m as usize).0.iter().for_each(|&j| add(j));
                    }
                });
                let qt = transpose_pattern(&q, nc);
                (q, qt)
            }
            None => (Pattern { ptr: vec![0], col: Vec::new() }, Pattern::default()),
        };
        let pt = p.transpose(nc);
        let lower = Pattern::union(nc, nc, |i, add| {
            add(i as u32);
            for &a in pt.row(i).0 {
                ap.row(a as usize).iter().filter(|&&j| j as usize <= i).for_each(|&j| add(j));
            }
            if !qt.ptr.is_empty() {
                for &t in qt.row(i) {
                    q.row(t as usize).iter().filter(|&&j| j as usize <= i).for_each(|&j| add(j));
                }
            }
        });
        LevelPatterns { ap, q, qt, coarse: Symmetric::new(&lower) }
    }

    /// The patterns of a coarse level's products: `a` times `p`.
    pub(crate) fn coarse(a: &CoarseBlocks, p: &CoarseBlocks, nc: usize) -> Self {
        let ap = Pattern::union(p.rows(), nc, |r, add| {
            for &b in a.row(r).0 {
                p.row(b as usize).0.iter().for_each(|&j| add(j));
            }
        });
        let pt = p.transpose(nc);
        let lower = Pattern::union(nc, nc, |i, add| {
            add(i as u32);
            for &r in pt.row(i).0 {
                ap.row(r as usize).iter().filter(|&&j| j as usize <= i).for_each(|&j| add(j));
            }
        });
        let empty = Pattern { ptr: vec![0], col: Vec::new() };
        LevelPatterns { ap, q: empty, qt: Pattern::default(), coarse: Symmetric::new(&lower) }
    }

    /// The Galerkin operator `Pᵀ K P` of the mesh's operator `k` (`pt` the transpose of
    /// `p`), with the products it was summed from.
    pub(crate) fn galerkin_fine(
        &self,
        k: &NodalMatrix,
        p: &FineP,
        pt: &Blocks<f64, 6, 3>,
    ) -> FineProducts {
        let nc = pt.rows();
        let e = &k.assembled;
        let ep = product(&self.ap, p.rows(), nc, |a, out, pos| {
            for s in e.ptr[a] as usize..e.ptr[a + 1] as usize {
                let kab = e.val[s];
                let (pc, pv) = p.row(e.col[s] as usize);
                for (&j, v) in pc.iter().zip(pv) {
                    out[pos[j as usize] as usize] += kab * v;
                }
            }
        });
        let q = k.nodal.as_ref().map(|c| {
            let mut q = vec![Row6::zeros(); self.q.col.len()];
            fill_rows(&self.q, &mut q, nc, |t, out, pos| {
                for m in c.c_ptr[t] as usize..c.c_ptr[t + 1] as usize {
                    let cv: Vector3<f64> = c.c_val[m];
                    let (pc, pv) = p.row(c.c_col[m] as usize);
                    for (&j, v) in pc.iter().zip(pv) {
                        out[pos[j as usize] as usize] += cv.transpose() * v;
                    }
                }
            });
            (c, q)
        });
        let mut a = Blocks::zeros(&self.coarse.pattern);
        let rows = a.rows_mut();
        let pat = &self.coarse.pattern;
        rows.into_par_iter().enumerate().with_min_len(8).for_each_init(
            || positions(nc),
            |pos, (i, out)| {
                let cols = pat.row(i);
                mark(pos, cols);
                let (nodes, pvals) = pt.row(i);
                for (&a, pa) in nodes.iter().zip(pvals) {
                    let (kc, kv) = ep.row(a as usize);
                    let end = kc.partition_point(|&j| j as usize <= i);
                    for (&j, v) in kc[..end].iter().zip(&kv[..end]) {
                        out[pos[j as usize] as usize] += pa * v;
                    }
                }
                if let Some((c, q)) = &q {
                    for &t in self.qt.row(i) {
                        let (lo, hi) =
                            (self.q.ptr[t as usize] as usize, self.q.ptr[t as usize + 1] as usize);
                        let cols = &self.q.col[lo..hi];
                        let vals = &q[lo..hi];
                        let k = cols.binary_search(&(i as u32)).expect("term in its column");
                        let qi = vals[k].transpose() * c.weight[t as usize];
                        let end = cols.partition_point(|&j| j as usize <= i);
                        for (&j, v) in cols[..end].iter().zip(&vals[..end]) {
                            out[pos[j as usize] as usize] += qi * v;
                        }
                    }
                }
                unmark(pos, cols);
            },
        );
        self.coarse.mirror_upper(&mut a);
        FineProducts { a1: a, ep, q: q.map(|(_, q)| q).unwrap_or_default() }
    }

    /// `C P`'s pattern (one row per nodal term) and its transpose.
    pub(crate) fn terms(&self) -> (&Pattern, &Pattern) {
        (&self.q, &self.qt)
    }

    /// The Galerkin operator `Pᵀ A P` of a coarse level's operator `a`.
    pub(crate) fn galerkin_coarse(
        &self,
        a: &CoarseBlocks,
        p: &CoarseBlocks,
        pt: &CoarseBlocks,
    ) -> CoarseBlocks {
        let nc = pt.rows();
        let ap = product(&self.ap, p.rows(), nc, |r, out, pos| {
            let (ac, av) = a.row(r);
            for (&b, ab) in ac.iter().zip(av) {
                let (pc, pv) = p.row(b as usize);
                for (&j, v) in pc.iter().zip(pv) {
                    out[pos[j as usize] as usize] += ab * v;
                }
            }
        });
        let mut g = Blocks::zeros(&self.coarse.pattern);
        let rows = g.rows_mut();
        let pat = &self.coarse.pattern;
        rows.into_par_iter().enumerate().with_min_len(8).for_each_init(
            || positions(nc),
            |pos, (i, out)| {
                let cols = pat.row(i);
                mark(pos, cols);
                let (nodes, pvals) = pt.row(i);
                for (&r, pr) in nodes.iter().zip(pvals) {
                    let (kc, kv) = ap.row(r as usize);
                    let end = kc.partition_point(|&j| j as usize <= i);
                    for (&j, v) in kc[..end].iter().zip(&kv[..end]) {
                        out[pos[j as usize] as usize] += pr * v;
                    }
                }
                unmark(pos, cols);
            },
        );
        self.coarse.mirror_upper(&mut g);
        g
    }
}

/// `A P` on `pattern` (`rows` rows, `nc` block columns): `each(row, out, positions)` adds
/// the row's products.
fn product<const R: usize>(
    pattern: &Pattern,
    rows: usize,
    nc: usize,
    each: impl Fn(usize, &mut [SMatrix<f64, R, 6>], &[u32]) + Sync,
) -> Blocks<f64, R, 6> {
    debug_assert_eq!(pattern.rows(), rows);
    let mut out = Blocks::zeros(pattern);
    let mut val = std::mem::take(&mut out.val);
    fill_rows(pattern, &mut val, nc, each);
    out.val = val;
    out
}

/// `val` (the entries of `pattern`) row by row: `each(row, out, positions)`.
fn fill_rows<T: Send>(
    pattern: &Pattern,
    val: &mut [T],
    nc: usize,
    each: impl Fn(usize, &mut [T], &[u32]) + Sync,
) {
    let rows = split_rows(&pattern.ptr, val);
    rows.into_par_iter().enumerate().with_min_len(64).for_each_init(
        || positions(nc),
        |pos, (r, out)| {
            let cols = pattern.row(r);
            mark(pos, cols);
            each(r, out, pos);
            unmark(pos, cols);
        },
    );
}

/// The transpose of a pattern with `columns` columns.
fn transpose_pattern(p: &Pattern, columns: usize) -> Pattern {
    let mut per: Vec<Vec<u32>> = vec![Vec::new(); columns];
    for r in 0..p.rows() {
        for &c in p.row(r) {
            per[c as usize].push(r as u32);
        }
    }
    let mut ptr = vec![0u32];
    for c in &per {
        ptr.push(ptr[ptr.len() - 1] + c.len() as u32);
    }
    Pattern { ptr, col: per.concat() }
}

/// `P = T − ω D⁻¹ (A T)`: the prolongator smoothed from the tentative `t` with `at = A T`
/// (its pattern contains `t`'s, which the products add), `inv_diag` the inverses of
/// `A`'s (projected) diagonal blocks.
pub(crate) fn smooth<const R: usize>(
    t: &Blocks<f64, R, 6>,
    at: &Blocks<f64, R, 6>,
    inv_diag: &[SMatrix<f64, R, R>],
    omega: f64,
) -> Blocks<f64, R, 6> {
    let mut p = at.clone();
    let ptr = p.ptr.clone();
    let col = p.col.clone();
    let rows = p.rows_mut();
    rows.into_par_iter().enumerate().with_min_len(64).for_each(|(a, row)| {
        let m = inv_diag[a] * -omega;
        for v in row.iter_mut() {
            *v = m * *v;
        }
        let (tc, tv) = t.row(a);
        let cols = &col[ptr[a] as usize..ptr[a + 1] as usize];
        for (&j, v) in tc.iter().zip(tv) {
            let k = cols.binary_search(&j).expect("T inside A T");
            row[k] += v;
        }
    });
    p
}

/// `A T` of the mesh's whole operator `k` (both parts) for the smoothing of the setup.
pub(crate) fn fine_times(k: &NodalMatrix, t: &FineP, nc: usize) -> FineP {
    let e = &k.assembled;
    let q = k.nodal.as_ref().map(|c| {
        let pattern = Pattern::union(c.terms(), nc, |tm, add| {
            for &m in &c.c_col[c.c_ptr[tm] as usize..c.c_ptr[tm + 1] as usize] {
                t.row(m as usize).0.iter().for_each(|&j| add(j));
            }
        });
        let mut vals = vec![Row6::zeros(); pattern.col.len()];
        fill_rows(&pattern, &mut vals, nc, |tm, out, pos| {
            for m in c.c_ptr[tm] as usize..c.c_ptr[tm + 1] as usize {
                let cv = c.c_val[m] * c.weight[tm];
                let (pc, pv) = t.row(c.c_col[m] as usize);
                for (&j, v) in pc.iter().zip(pv) {
                    out[pos[j as usize] as usize] += cv.transpose() * v;
                }
            }
        });
        (c, pattern, vals)
    });
    // T's own entries too: a node no element holds (a resected region's) has an empty row
    // of A, and the smoothing adds T into A T's pattern.
    let pattern = Pattern::union(t.rows(), nc, |a, add| {
        t.row(a).0.iter().for_each(|&j| add(j));
        for &b in &e.col[e.ptr[a] as usize..e.ptr[a + 1] as usize] {
            t.row(b as usize).0.iter().for_each(|&j| add(j));
        }
        if let Some((c, qp, _)) = &q {
            for &tm in &c.t_col[c.t_ptr[a] as usize..c.t_ptr[a + 1] as usize] {
                qp.row(tm as usize).iter().for_each(|&j| add(j));
            }
        }
    });
    product(&pattern, t.rows(), nc, |a, out, pos| {
        for s in e.ptr[a] as usize..e.ptr[a + 1] as usize {
            let kab = e.val[s];
            let (pc, pv) = t.row(e.col[s] as usize);
            for (&j, v) in pc.iter().zip(pv) {
                out[pos[j as usize] as usize] += kab * v;
            }
        }
        if let Some((c, qp, qv)) = &q {
            for m in c.t_ptr[a] as usize..c.t_ptr[a + 1] as usize {
                let (cv, tm) = (c.t_val[m], c.t_col[m] as usize);
                let (lo, hi) = (qp.ptr[tm] as usize, qp.ptr[tm + 1] as usize);
                for (&j, v) in qp.col[lo..hi].iter().zip(&qv[lo..hi]) {
                    out[pos[j as usize] as usize] += cv * v;
                }
            }
        }
    })
}

/// `A T` of a coarse operator `a` (the setup's smoothing).
pub(crate) fn coarse_times(a: &CoarseBlocks, t: &CoarseBlocks, nc: usize) -> CoarseBlocks {
    let pattern = Pattern::union(t.rows(), nc, |r, add| {
        t.row(r).0.iter().for_each(|&j| add(j));
        for &b in a.row(r).0 {
            t.row(b as usize).0.iter().for_each(|&j| add(j));
        }
    });
    product(&pattern, t.rows(), nc, |r, out, pos| {
        let (ac, av) = a.row(r);
        for (&b, ab) in ac.iter().zip(av) {
            let (pc, pv) = t.row(b as usize);
            for (&j, v) in pc.iter().zip(pv) {
                out[pos[j as usize] as usize] += ab * v;
            }
        }
    })
}
