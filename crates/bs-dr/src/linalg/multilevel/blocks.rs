//! Block-sparse matrices of the hierarchy: one block row per node of a level (3 rows on the
//! mesh, 6 on the coarse levels, one per rigid-body mode of an aggregate) and block columns
//! of 6 (the coarse unknowns of an aggregate), or of 6 × 6 for the coarse operators. A
//! block is a static nalgebra matrix, so the products are small dense kernels with one
//! index per block instead of one per scalar. Patterns are computed once ([`Pattern`]) and
//! the numbers written into them as often as the operator changes.

use nalgebra::{RealField, SMatrix, Scalar};
use rayon::prelude::*;

use crate::linalg::sparse::split_rows;

/// A block-sparse matrix with `R × C` blocks in compressed rows, columns increasing in
/// every row.
#[derive(Debug, Clone)]
pub(crate) struct Blocks<T: Scalar, const R: usize, const C: usize> {
    pub(super) ptr: Vec<u32>,
    pub(super) col: Vec<u32>,
    pub(super) val: Vec<SMatrix<T, R, C>>,
}

/// No position (a column not in the row being summed).
pub(super) const NONE: u32 = u32::MAX;

impl<T: RealField + Copy, const R: usize, const C: usize> Blocks<T, R, C> {
    /// A matrix of `pattern` with zero blocks.
    pub(crate) fn zeros(pattern: &Pattern) -> Self {
        Blocks {
            ptr: pattern.ptr.clone(),
            col: pattern.col.clone(),
            val: vec![SMatrix::zeros(); pattern.col.len()],
        }
    }

    /// The rows in compressed form.
    #[cfg(test)]
    pub(crate) fn from_rows(rows: Vec<Vec<(u32, SMatrix<T, R, C>)>>) -> Self {
        let mut ptr = Vec::with_capacity(rows.len() + 1);
        ptr.push(0u32);
        for r in &rows {
            ptr.push(ptr[ptr.len() - 1] + r.len() as u32);
        }
        let (col, val) = rows.into_iter().flatten().unzip();
        Blocks { ptr, col, val }
    }

    /// Number of block rows.
    pub(crate) fn rows(&self) -> usize {
        self.ptr.len() - 1
    }

    /// Number of blocks.
    pub(crate) fn len(&self) -> usize {
        self.val.len()
    }

    /// Row `a`: block columns and blocks.
    #[inline]
    pub(crate) fn row(&self, a: usize) -> (&[u32], &[SMatrix<T, R, C>]) {
        let (lo, hi) = (self.ptr[a] as usize, self.ptr[a + 1] as usize);
        (&self.col[lo..hi], &self.val[lo..hi])
    }

    /// The blocks cut into rows (disjoint, for row-parallel writes).
    pub(crate) fn rows_mut(&mut self) -> Vec<&mut [SMatrix<T, R, C>]> {
        split_rows(&self.ptr, &mut self.val)
    }

    /// The transpose with the blocks of `self` (a matrix of the pattern `map` was made
    /// for, [`transpose_map`](Self::transpose_map)): `out`'s pattern kept, its blocks
    /// written.
    pub(crate) fn transpose_into(&self, map: &[u32], out: &mut Blocks<T, C, R>)
    where
        T: Send + Sync,
    {
        out.val.par_iter_mut().zip(map.par_iter()).with_min_len(1024).for_each(|(o, &k)| {
            *o = self.val[k as usize].transpose();
        });
    }

    /// Per block of the transpose ([`transpose`](Self::transpose) with `columns`), the
    /// position of its block in `self`.
    pub(crate) fn transpose_map(&self, columns: usize) -> Vec<u32> {
        let mut ptr = vec![0u32; columns + 1];
        for &c in &self.col {
            ptr[c as usize + 1] += 1;
        }
        for i in 0..columns {
            ptr[i + 1] += ptr[i];
        }
        let mut map = vec![0u32; self.col.len()];
        for (k, &c) in self.col.iter().enumerate() {
            map[ptr[c as usize] as usize] = k as u32;
            ptr[c as usize] += 1;
        }
        map
    }

    /// The transpose (`columns` block columns become the rows), rows increasing in every
    /// column.
    pub(crate) fn transpose(&self, columns: usize) -> Blocks<T, C, R> {
        let mut ptr = vec![0u32; columns + 1];
        for &c in &self.col {
            ptr[c as usize + 1] += 1;
        }
        for i in 0..columns {
            ptr[i + 1] += ptr[i];
        }
        let mut fill = ptr.clone();
        let mut col = vec![0u32; self.col.len()];
        let mut val = vec![SMatrix::<T, C, R>::zeros(); self.col.len()];
        for a in 0..self.rows() {
            let (cols, vals) = self.row(a);
            for (&c, v) in cols.iter().zip(vals) {
                let k = fill[c as usize] as usize;
                col[k] = a as u32;
                val[k] = v.transpose();
                fill[c as usize] += 1;
            }
        }
        Blocks { ptr, col, val }
    }
}

impl<const R: usize, const C: usize> Blocks<f64, R, C> {
    /// The same blocks in single precision (the cycle's copies: half the bytes).
    pub(crate) fn to_f32(&self) -> Blocks<f32, R, C> {
        Blocks {
            ptr: self.ptr.clone(),
            col: self.col.clone(),
            val: self.val.par_iter().map(|b| b.cast::<f32>()).collect(),
        }
    }
}

/// A row pattern: offsets and increasing columns per row.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Pattern {
    pub(super) ptr: Vec<u32>,
    pub(super) col: Vec<u32>,
}

impl Pattern {
    /// The sorted union of the columns (below `columns`) that `each(r, add)` adds, for every
    /// row `r < rows`.
    pub(crate) fn union(
        rows: usize,
        columns: usize,
        each: impl Fn(usize, &mut dyn FnMut(u32)) + Sync,
    ) -> Self {
        let per_row: Vec<Vec<u32>> = (0..rows)
            .into_par_iter()
            .with_min_len(64)
            .map_init(
                || vec![false; columns],
                |mark, r| {
                    let mut cols = Vec::new();
                    each(r, &mut |c| {
                        if !mark[c as usize] {
                            mark[c as usize] = true;
                            cols.push(c);
                        }
                    });
                    cols.iter().for_each(|&c| mark[c as usize] = false);
                    cols.sort_unstable();
                    cols
                },
            )
            .collect();
        let mut ptr = Vec::with_capacity(rows + 1);
        ptr.push(0u32);
        for c in &per_row {
            ptr.push(ptr[ptr.len() - 1] + c.len() as u32);
        }
        Pattern { ptr, col: per_row.concat() }
    }

    /// Columns of row `r`.
    #[inline]
    pub(crate) fn row(&self, r: usize) -> &[u32] {
        &self.col[self.ptr[r] as usize..self.ptr[r + 1] as usize]
    }

    /// Number of rows.
    pub(crate) fn rows(&self) -> usize {
        self.ptr.len() - 1
    }
}

/// Positions of a row's columns in a dense scratch of the column count: set for the row
/// being summed, reset after.
pub(super) fn mark(pos: &mut [u32], cols: &[u32]) {
    for (k, &c) in cols.iter().enumerate() {
        pos[c as usize] = k as u32;
    }
}

/// Resets the positions [`mark`] set.
pub(super) fn unmark(pos: &mut [u32], cols: &[u32]) {
    cols.iter().for_each(|&c| pos[c as usize] = NONE);
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::SMatrix;

    fn sample() -> Blocks<f64, 3, 6> {
        let b = |s: f64| SMatrix::<f64, 3, 6>::from_fn(|i, j| s * (1 + i + 3 * j) as f64);
        Blocks::from_rows(vec![
            vec![(0, b(1.0)), (3, b(2.0))],
            vec![],
            vec![(1, b(3.0)), (2, b(4.0)), (3, b(5.0))],
        ])
    }

    #[test]
    fn the_transpose_holds_every_block_once_transposed() {
        let p = sample();
        let t = p.transpose(4);
        assert_eq!(t.ptr, vec![0, 1, 2, 3, 5]);
        assert_eq!(t.row(3).0, &[0, 2]);
        assert_eq!(t.row(3).1[1], p.row(2).1[2].transpose());
        assert_eq!(t.transpose(3).val, p.val);
        let mut again = t.clone();
        again.val.iter_mut().for_each(|b| *b = SMatrix::zeros());
        p.transpose_into(&p.transpose_map(4), &mut again);
        assert_eq!(again.val, t.val);
    }

    #[test]
    fn a_union_is_sorted_and_without_repeats() {
        let p = Pattern::union(3, 10, |r, add| {
            for c in [7, 2, 7, r as u32, 2] {
                add(c);
            }
        });
        assert_eq!(p.row(0), &[0, 2, 7]);
        assert_eq!(p.row(2), &[2, 7]);
        assert_eq!(p.rows(), 3);
    }
}
