//! Sparse matrices with one row per node and scalar columns (the prolongator `P` and `K₀ P`),
//! the accumulator that builds their rows, and the products of the setup: `Pᵀ` and `K₀ P`.

use bs_mesh::Vector3;
use rayon::prelude::*;

use crate::linalg::sparse::{BlockCsr, RankOneSum, split_rows};

/// A sparse matrix with one row per node (three scalar rows) and scalar columns: row `a`
/// holds `(column, 3-vector)` entries, in double precision (`V = Vector3<f64>`, the setup's
/// form) or single ([`NodeRows32`], the cycle's).
#[derive(Debug, Clone, Default)]
pub(crate) struct NodeRows<V = Vector3<f64>> {
    pub(super) ptr: Vec<u32>,
    pub(super) col: Vec<u32>,
    pub(super) val: Vec<V>,
}

/// [`NodeRows`] with single-precision entries: the prolongator and its transpose as the
/// cycle reads them (half the bytes; products accumulate in double precision).
pub(crate) type NodeRows32 = NodeRows<[f32; 3]>;

impl NodeRows {
    /// The rows in compressed form (copied in parallel, row by row).
    pub(crate) fn from_rows(rows: Vec<Vec<(u32, Vector3<f64>)>>) -> Self {
        let mut ptr = Vec::with_capacity(rows.len() + 1);
        ptr.push(0u32);
        for r in &rows {
            ptr.push(ptr[ptr.len() - 1] + r.len() as u32);
        }
        let total = ptr[rows.len()] as usize;
        let mut col = vec![0u32; total];
        let mut val = vec![Vector3::zeros(); total];
        let mut cols = split_rows(&ptr, &mut col);
        let mut vals = split_rows(&ptr, &mut val);
        rows.into_par_iter()
            .zip(cols.par_iter_mut())
            .zip(vals.par_iter_mut())
            .with_min_len(256)
            .for_each(|((r, c), v)| {
                for (k, (j, x)) in r.into_iter().enumerate() {
                    c[k] = j;
                    v[k] = x;
                }
            });
        NodeRows { ptr, col, val }
    }

    /// The same rows with single-precision entries.
    pub(crate) fn to_f32(&self) -> NodeRows32 {
        let val = self.val.par_iter().map(|v| [v.x as f32, v.y as f32, v.z as f32]).collect();
        NodeRows { ptr: self.ptr.clone(), col: self.col.clone(), val }
    }
}

impl<V> NodeRows<V> {
    /// Row `a`: columns and entries.
    pub(crate) fn row(&self, a: usize) -> (&[u32], &[V]) {
        let (lo, hi) = (self.ptr[a] as usize, self.ptr[a + 1] as usize);
        (&self.col[lo..hi], &self.val[lo..hi])
    }

    /// Number of rows.
    pub(crate) fn rows(&self) -> usize {
        self.ptr.len() - 1
    }

    /// Number of entries.
    pub(crate) fn len(&self) -> usize {
        self.val.len()
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

/// `Pᵀ` as per-column rows of `(node, 3-vector)`, nodes increasing (a counting sort).
pub(crate) fn transpose(p: &NodeRows, nc: usize) -> NodeRows {
    let mut ptr = vec![0u32; nc + 1];
    for &c in &p.col {
        ptr[c as usize + 1] += 1;
    }
    for i in 0..nc {
        ptr[i + 1] += ptr[i];
    }
    let mut fill = ptr.clone();
    let mut col = vec![0u32; p.col.len()];
    let mut val = vec![Vector3::zeros(); p.col.len()];
    for a in 0..p.rows() {
        let (cols, vals) = p.row(a);
        for (&c, v) in cols.iter().zip(vals) {
            let k = fill[c as usize] as usize;
            col[k] = a as u32;
            val[k] = *v;
            fill[c as usize] += 1;
        }
    }
    NodeRows { ptr, col, val }
}

/// `K₀ P` (node rows) of `K₀ = E + Cᵀ W C` (`nodal` the rank-one part, if any).
pub(crate) fn product(e: &BlockCsr, nodal: Option<&RankOneSum>, p: &NodeRows) -> NodeRows {
    let n = p.rows();
    let nc = tentative_columns(p);
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
    if let Some(nodal) = nodal {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A 5-node, 4-column matrix with rows of different lengths (one empty).
    fn sample() -> NodeRows {
        let v = |a: f64| Vector3::new(a, -a, 2.0 * a);
        NodeRows::from_rows(vec![
            vec![(0, v(1.0)), (3, v(2.0))],
            vec![],
            vec![(1, v(3.0)), (2, v(4.0)), (3, v(5.0))],
            vec![(0, v(6.0))],
            vec![(2, v(7.0))],
        ])
    }

    #[test]
    fn rows_are_stored_as_given() {
        let p = sample();
        assert_eq!(p.ptr, vec![0, 2, 2, 5, 6, 7]);
        assert_eq!(p.row(2).0, &[1, 2, 3]);
        assert_eq!(p.row(2).1[1], Vector3::new(4.0, -4.0, 8.0));
        assert!(p.row(1).0.is_empty());
    }

    #[test]
    fn the_transpose_holds_every_entry_once_with_nodes_increasing() {
        let p = sample();
        let pt = transpose(&p, tentative_columns(&p));
        assert_eq!(pt.rows(), 4);
        let mut count = 0;
        for c in 0..4 {
            let (nodes, vals) = pt.row(c);
            assert!(nodes.windows(2).all(|w| w[0] < w[1]));
            for (&a, v) in nodes.iter().zip(vals) {
                let (cols, pv) = p.row(a as usize);
                let k = cols.iter().position(|&j| j as usize == c).expect("entry of P");
                assert_eq!(pv[k], *v);
                count += 1;
            }
        }
        assert_eq!(count, p.col.len());
    }
}
