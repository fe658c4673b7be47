//! Sparse matrices with one row per node and scalar columns (the prolongator `P` and `K₀ P`),
//! the accumulator that builds their rows, and the products of the setup: `Pᵀ` and `K₀ P`.

use bs_mesh::Vector3;
use rayon::prelude::*;

use crate::linalg::nodal::NodalMatrix;

/// A sparse matrix with one row per node (three scalar rows) and scalar columns: row `a`
/// holds `(column, 3-vector)` entries.
#[derive(Debug, Clone, Default)]
pub(crate) struct NodeRows {
    pub(super) ptr: Vec<u32>,
    pub(super) col: Vec<u32>,
    pub(super) val: Vec<Vector3<f64>>,
}

impl NodeRows {
    pub(crate) fn from_rows(rows: Vec<Vec<(u32, Vector3<f64>)>>) -> Self {
        let mut ptr = Vec::with_capacity(rows.len() + 1);
        ptr.push(0);
        let total = rows.iter().map(Vec::len).sum();
        let mut col = Vec::with_capacity(total);
        let mut val = Vec::with_capacity(total);
        for r in rows {
            for (c, v) in r {
                col.push(c);
                val.push(v);
            }
            ptr.push(col.len() as u32);
        }
        NodeRows { ptr, col, val }
    }

    pub(crate) fn row(&self, a: usize) -> (&[u32], &[Vector3<f64>]) {
        let (lo, hi) = (self.ptr[a] as usize, self.ptr[a + 1] as usize);
        (&self.col[lo..hi], &self.val[lo..hi])
    }

    pub(crate) fn rows(&self) -> usize {
        self.ptr.len() - 1
    }
}

/// Sparse accumulator over `n` columns (dense values, touched list).
pub(crate) struct Accumulator<T> {
    pub(super) val: Vec<T>,
    pub(super) mark: Vec<bool>,
    pub(super) touched: Vec<u32>,
}

impl<T: Copy + Default + std::ops::AddAssign> Accumulator<T> {
    pub(crate) fn new(n: usize) -> Self {
        Accumulator { val: vec![T::default(); n], mark: vec![false; n], touched: Vec::new() }
    }

    #[inline]
    pub(crate) fn add(&mut self, c: u32, v: T) {
        let k = c as usize;
        if !self.mark[k] {
            self.mark[k] = true;
            self.val[k] = T::default();
            self.touched.push(c);
        }
        self.val[k] += v;
    }

    /// The accumulated entries in increasing column order; resets.
    pub(crate) fn drain(&mut self) -> Vec<(u32, T)> {
        self.touched.sort_unstable();
        let out = self.touched.iter().map(|&c| (c, self.val[c as usize])).collect();
        for &c in &self.touched {
            self.mark[c as usize] = false;
        }
        self.touched.clear();
        out
    }
}

/// Number of columns of `p` (its largest column index + 1).
pub(crate) fn tentative_columns(p: &NodeRows) -> usize {
    p.col.iter().map(|&c| c as usize + 1).max().unwrap_or(0)
}

/// `Pᵀ` as per-column rows of `(node, 3-vector)`.
pub(crate) fn transpose(p: &NodeRows, nc: usize) -> NodeRows {
    let mut rows: Vec<Vec<(u32, Vector3<f64>)>> = vec![Vec::new(); nc];
    for a in 0..p.rows() {
        let (cols, vals) = p.row(a);
        for (&c, v) in cols.iter().zip(vals) {
            rows[c as usize].push((a as u32, *v));
        }
    }
    NodeRows::from_rows(rows)
}

/// `K₀ P` (node rows).
pub(crate) fn product(k: &NodalMatrix, p: &NodeRows) -> NodeRows {
    let n = p.rows();
    let nc = tentative_columns(p);
    let e = &k.assembled;
    let mut rows: Vec<Vec<(u32, Vector3<f64>)>> = (0..n)
        .into_par_iter()
        .with_min_len(128)
        .map_init(
            || Accumulator::<Vector3<f64>>::new(nc),
            |acc, a| {
                for q in e.ptr[a] as usize..e.ptr[a + 1] as usize {
                    let kab = e.val[q];
                    let (cols, vals) = p.row(e.col[q] as usize);
                    for (&c, v) in cols.iter().zip(vals) {
                        acc.add(c, kab * v);
                    }
                }
                acc.drain()
            },
        )
        .collect();
    if let Some(nodal) = &k.nodal {
        // Q = C P (one sparse scalar row per term), then Cᵀ W Q.
        let q: Vec<Vec<(u32, f64)>> = (0..nodal.terms())
            .into_par_iter()
            .with_min_len(128)
            .map_init(
                || Accumulator::<f64>::new(nc),
                |acc, t| {
                    for m in nodal.c_ptr[t] as usize..nodal.c_ptr[t + 1] as usize {
                        let c = nodal.c_val[m];
                        let (cols, vals) = p.row(nodal.c_col[m] as usize);
                        for (&j, v) in cols.iter().zip(vals) {
                            acc.add(j, nodal.weight[t] * c.dot(v));
                        }
                    }
                    acc.drain()
                },
            )
            .collect();
        rows.par_iter_mut().enumerate().with_min_len(128).for_each_init(
            || Accumulator::<Vector3<f64>>::new(nc),
            |acc, (a, row)| {
                for &(c, v) in row.iter() {
                    acc.add(c, v);
                }
                for m in nodal.t_ptr[a] as usize..nodal.t_ptr[a + 1] as usize {
                    let c = nodal.t_val[m];
                    for &(j, s) in &q[nodal.t_col[m] as usize] {
                        acc.add(j, c * s);
                    }
                }
                *row = acc.drain();
            },
        );
    }
    NodeRows::from_rows(rows)
}
