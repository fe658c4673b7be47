//! Nodal sparse matrices and vector kernels for the Newton–Krylov solver.
//!
//! Vectors are nodal (`[Vector3<f64>]`, one entry per mesh node), the layout of the force
//! kernels. Every parallel kernel here gives bit-identical results for any number of rayon
//! threads: rows are independent, and reductions sum fixed-size chunks in parallel and then
//! the chunk sums in order.

use bs_mesh::Vector3;
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::kernels::simd::Lanes;

/// Nodes per rayon task in the row-parallel kernels.
const MIN_ROWS: usize = 256;
/// Entries per chunk of a deterministic reduction.
const CHUNK: usize = 2048;

/// Euclidean dot product of two nodal vectors, deterministic for any thread count.
pub fn dot(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    let partial: Vec<f64> = a
        .par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(x, y)| x.iter().zip(y).map(|(p, q)| p.dot(q)).sum::<f64>())
        .collect();
    partial.iter().sum()
}

/// Euclidean norm of a nodal vector.
pub fn norm(a: &[Vector3<f64>]) -> f64 {
    dot(a, a).sqrt()
}

/// Largest component magnitude of a nodal vector.
pub fn max_abs(a: &[Vector3<f64>]) -> f64 {
    a.par_chunks(CHUNK)
        .map(|x| x.iter().fold(0.0f64, |m, v| m.max(v.amax())))
        .reduce(|| 0.0, f64::max)
}

/// `y += alpha x`.
pub fn axpy(alpha: f64, x: &[Vector3<f64>], y: &mut [Vector3<f64>]) {
    y.par_iter_mut().zip(x.par_iter()).with_min_len(CHUNK).for_each(|(b, a)| *b += a * alpha);
}

/// `K` vectors of one length cut into tasks of `rows` entries: task `i` holds entries
/// `i·rows..(i+1)·rows` of each (for a parallel pass that writes all of them).
pub(crate) fn batch_chunks<T, const K: usize>(
    out: [&mut [T]; K],
    rows: usize,
) -> Vec<[&mut [T]; K]> {
    let len = out.first().map_or(0, |o| o.len());
    debug_assert!(out.iter().all(|o| o.len() == len));
    let mut chunks: [_; K] = out.map(|o| o.chunks_mut(rows));
    (0..len.div_ceil(rows))
        .map(|_| std::array::from_fn(|j| chunks[j].next().expect("K vectors of one length")))
        .collect()
}

/// `data` cut into the rows of the offsets `ptr` (disjoint mutable slices).
pub(crate) fn split_rows<'a, T>(ptr: &[u32], data: &'a mut [T]) -> Vec<&'a mut [T]> {
    let mut rest = data;
    let mut out = Vec::with_capacity(ptr.len().saturating_sub(1));
    for w in ptr.windows(2) {
        let (head, tail) = std::mem::take(&mut rest).split_at_mut((w[1] - w[0]) as usize);
        out.push(head);
        rest = tail;
    }
    out
}

/// A symmetric sparse matrix of 3×3 blocks in compressed rows, both triangles stored
/// (rows are independent, so the product is parallel and deterministic).
#[derive(Debug, Clone, Default)]
pub struct BlockCsr {
    /// Row offsets (length = nodes + 1).
    pub ptr: Vec<u32>,
    /// Column (node) of each block, increasing within a row.
    pub col: Vec<u32>,
    /// The blocks.
    pub val: Vec<Matrix3<f64>>,
}

impl BlockCsr {
    /// The pattern of the node graph `adjacency` (each row sorted, diagonal included) with
    /// zero blocks.
    pub fn from_pattern(adjacency: &[Vec<u32>]) -> Self {
        let mut ptr = Vec::with_capacity(adjacency.len() + 1);
        ptr.push(0u32);
        let mut col = Vec::new();
        for row in adjacency {
            col.extend_from_slice(row);
            ptr.push(col.len() as u32);
        }
        let val = vec![Matrix3::zeros(); col.len()];
        BlockCsr { ptr, col, val }
    }

    /// Number of block rows.
    pub fn rows(&self) -> usize {
        self.ptr.len() - 1
    }

    /// Position of block `(r, c)` in `val`, if it is in the pattern.
    pub fn find(&self, r: usize, c: usize) -> Option<usize> {
        let (lo, hi) = (self.ptr[r] as usize, self.ptr[r + 1] as usize);
        self.col[lo..hi].binary_search(&(c as u32)).ok().map(|k| lo + k)
    }

    /// The diagonal block of row `r` (zero if absent).
    pub fn diagonal(&self, r: usize) -> Matrix3<f64> {
        self.find(r, r).map_or_else(Matrix3::zeros, |k| self.val[k])
    }

    /// `y = A x`.
    pub fn mul(&self, x: &[Vector3<f64>], y: &mut [Vector3<f64>]) {
        y.par_iter_mut().enumerate().with_min_len(MIN_ROWS).for_each(|(r, yr)| {
            let (lo, hi) = (self.ptr[r] as usize, self.ptr[r + 1] as usize);
            let mut acc = Vector3::zeros();
            for k in lo..hi {
                acc += self.val[k] * x[self.col[k] as usize];
            }
            *yr = acc;
        });
    }
}

/// A sum of rank-one nodal terms `Σ_n w_n c_n c_nᵀ`, each `c_n` a sparse nodal vector:
/// the linearised volumetric stiffness of the average-nodal-pressure tetrahedron, whose
/// assembled form would couple every node with its two-ring (about five times the nonzeros
/// of the element stiffness). Stored as the rows of `C` (term → nodes) and of `Cᵀ`
/// (node → terms) so that both products are row-parallel and deterministic.
#[derive(Debug, Clone, Default)]
pub struct RankOneSum {
    /// Weight of each term.
    pub weight: Vec<f64>,
    /// Rows of `C`: term offsets, nodes and nodal 3-vectors.
    pub c_ptr: Vec<u32>,
    /// Node of each entry of `C`.
    pub c_col: Vec<u32>,
    /// Entries of `C`.
    pub c_val: Vec<Vector3<f64>>,
    /// Rows of `Cᵀ`: node offsets, terms and the same 3-vectors.
    pub t_ptr: Vec<u32>,
    /// Term of each entry of `Cᵀ`.
    pub t_col: Vec<u32>,
    /// Entries of `Cᵀ`.
    pub t_val: Vec<Vector3<f64>>,
}

impl RankOneSum {
    /// Builds both storages from the rows of `C` (entries per term, nodes increasing).
    pub fn new(weight: Vec<f64>, rows: &[Vec<(u32, Vector3<f64>)>], nodes: usize) -> Self {
        let mut c_ptr = vec![0u32];
        let mut c_col = Vec::new();
        let mut c_val = Vec::new();
        let mut count = vec![0u32; nodes + 1];
        for row in rows {
            for &(n, v) in row {
                c_col.push(n);
                c_val.push(v);
                count[n as usize + 1] += 1;
            }
            c_ptr.push(c_col.len() as u32);
        }
        for i in 0..nodes {
            count[i + 1] += count[i];
        }
        let t_ptr = count.clone();
        let mut fill = count;
        let mut t_col = vec![0u32; c_col.len()];
        let mut t_val = vec![Vector3::zeros(); c_col.len()];
        for (term, row) in rows.iter().enumerate() {
            for &(n, v) in row {
                let k = fill[n as usize] as usize;
                t_col[k] = term as u32;
                t_val[k] = v;
                fill[n as usize] += 1;
            }
        }
        RankOneSum { weight, c_ptr, c_col, c_val, t_ptr, t_col, t_val }
    }

    /// Number of terms.
    pub fn terms(&self) -> usize {
        self.weight.len()
    }

    /// `s = W C x` (one scalar per term) into `s`.
    pub fn project_into(&self, x: &[Vector3<f64>], s: &mut [f64]) {
        s.par_iter_mut().enumerate().with_min_len(MIN_ROWS).for_each(|(t, st)| {
            *st = self.project_row(t, x);
        });
    }

    /// `y += Cᵀ s`.
    pub fn add_expand(&self, s: &[f64], y: &mut [Vector3<f64>]) {
        y.par_iter_mut().enumerate().with_min_len(MIN_ROWS).for_each(|(n, yn)| {
            *yn += self.expand_row(n, s);
        });
    }

    /// `(Cᵀ s)_n`: row `n` of [`add_expand`](Self::add_expand), for passes that do more
    /// per node.
    #[inline]
    pub fn expand_row(&self, n: usize, s: &[f64]) -> Vector3<f64> {
        let (lo, hi) = (self.t_ptr[n] as usize, self.t_ptr[n + 1] as usize);
        let mut acc = Vector3::zeros();
        for k in lo..hi {
            acc += self.t_val[k] * s[self.t_col[k] as usize];
        }
        acc
    }

    /// `(W C x)_t`: term `t` of [`project_into`](Self::project_into).
    #[inline]
    pub fn project_row(&self, t: usize, x: &[Vector3<f64>]) -> f64 {
        let (lo, hi) = (self.c_ptr[t] as usize, self.c_ptr[t + 1] as usize);
        let mut acc = 0.0;
        for k in lo..hi {
            acc += self.c_val[k].dot(&x[self.c_col[k] as usize]);
        }
        self.weight[t] * acc
    }
}

/// [`RankOneSum`] with single-precision entries padded to four lanes: an entry times a value
/// is one fused multiply-add on four f64 lanes after an exact widening.
#[derive(Debug, Clone, Default)]
pub struct RankOneSum32 {
    weight: Vec<f64>,
    c_ptr: Vec<u32>,
    c_col: Vec<u32>,
    c_val: Vec<[f32; 4]>,
    t_ptr: Vec<u32>,
    t_col: Vec<u32>,
    t_val: Vec<[f32; 4]>,
}

impl From<&RankOneSum> for RankOneSum32 {
    fn from(a: &RankOneSum) -> Self {
        let f = |v: &Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32, 0.0];
        RankOneSum32 {
            weight: a.weight.clone(),
            c_ptr: a.c_ptr.clone(),
            c_col: a.c_col.clone(),
            c_val: a.c_val.iter().map(f).collect(),
            t_ptr: a.t_ptr.clone(),
            t_col: a.t_col.clone(),
            t_val: a.t_val.iter().map(f).collect(),
        }
    }
}

impl RankOneSum32 {
    /// Number of terms.
    pub fn terms(&self) -> usize {
        self.weight.len()
    }

    /// `s = W C x` (one value per term).
    pub fn project_into(&self, x: &[Vector3<f64>], s: &mut [f64]) {
        s.par_iter_mut().enumerate().with_min_len(MIN_ROWS).for_each(|(t, st)| {
            let (lo, hi) = (self.c_ptr[t] as usize, self.c_ptr[t + 1] as usize);
            let mut acc = 0.0;
            for (c, &n) in self.c_val[lo..hi].iter().zip(&self.c_col[lo..hi]) {
                let v = &x[n as usize];
                acc += c[0] as f64 * v.x + c[1] as f64 * v.y + c[2] as f64 * v.z;
            }
            *st = self.weight[t] * acc;
        });
    }

    /// `acc + (Cᵀ s)_n` on lanes `l`.
    #[inline(always)]
    pub(crate) fn expand_row_lanes<L: Lanes>(&self, l: L, n: usize, s: &[f64], acc: L::V) -> L::V {
        let (lo, hi) = (self.t_ptr[n] as usize, self.t_ptr[n + 1] as usize);
        let mut acc = acc;
        for (c, &t) in self.t_val[lo..hi].iter().zip(&self.t_col[lo..hi]) {
            acc = l.mul_add(l.load_f32(*c), l.splat(s[t as usize]), acc);
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_is_the_same_for_one_and_two_threads() {
        let a: Vec<Vector3<f64>> = (0..10_000)
            .map(|i| Vector3::new((i as f64).sin(), 1.0 / (1.0 + i as f64), 0.3))
            .collect();
        let b: Vec<Vector3<f64>> =
            (0..10_000).map(|i| Vector3::new(1.0, (i as f64).cos(), -2.0)).collect();
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let d1 = one.install(|| dot(&a, &b));
        let d2 = two.install(|| dot(&a, &b));
        assert_eq!(d1.to_bits(), d2.to_bits());
        let naive: f64 = a.iter().zip(&b).map(|(x, y)| x.dot(y)).sum();
        assert!((d1 - naive).abs() <= 1e-12 * naive.abs().max(1.0));
    }

    #[test]
    fn rank_one_sum_equals_its_dense_form() {
        // Two terms on three nodes.
        let rows = vec![
            vec![(0u32, Vector3::new(1.0, 2.0, 0.0)), (2, Vector3::new(0.0, -1.0, 3.0))],
            vec![(1u32, Vector3::new(0.5, 0.0, 1.0)), (2, Vector3::new(2.0, 1.0, 0.0))],
        ];
        let r = RankOneSum::new(vec![2.0, 3.0], &rows, 3);
        let x = vec![
            Vector3::new(1.0, -1.0, 2.0),
            Vector3::new(0.0, 4.0, 1.0),
            Vector3::new(3.0, 0.5, -1.0),
        ];
        let mut s = vec![0.0; 2];
        r.project_into(&x, &mut s);
        let mut y = vec![Vector3::zeros(); 3];
        r.add_expand(&s, &mut y);
        // dense: y_m = Σ_t w_t c_tm (Σ_k c_tk · x_k)
        let mut expect = vec![Vector3::zeros(); 3];
        for (t, row) in rows.iter().enumerate() {
            let w = [2.0, 3.0][t];
            let proj: f64 = row.iter().map(|(n, c)| c.dot(&x[*n as usize])).sum();
            for (n, c) in row {
                expect[*n as usize] += c * (w * proj);
            }
        }
        for (a, b) in y.iter().zip(&expect) {
            assert!((a - b).norm() < 1e-12);
        }
    }
}
