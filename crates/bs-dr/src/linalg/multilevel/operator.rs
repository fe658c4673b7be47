//! `K₀ = E + Cᵀ W C` in single precision, fused for the smoother: two passes over the rows
//! of one shared node pattern instead of three over three structures.
//!
//! For the T4ANP volumetric term every node `r` has its own term `c_r` (its averaging group),
//! whose support is the nodes sharing a tetrahedron with `r`: the pattern of `E`'s row `r`.
//! So `Cᵀ`'s entry `(r, c)` (term `c`'s 3-vector at node `r`) fits in the slot of block
//! `E_rc`, and each slot holds the three rows of the 3×4 matrix `[E_rc | (c_c)_r]` — the 12
//! floats a padded 3×3 block took. With `x̂_c = (x_c, s_c)`, `s_c = w_c c_c·x` (pass one, which
//! reads `c_r`'s entries `(c_r)_c` from a second array on the same slots), row `r` of `K₀ x` is
//! `Σ_c [E_rc | (c_c)_r] x̂_c` (pass two): one aligned 4-lane load of `x̂_c` and three fused
//! multiply-adds per slot. Terms beyond the nodes (the extra groups of nodes shared by two
//! solids) stay a separate [`RankOneSum32`].
//!
//! 72 bytes per slot against the 92 of a padded block plus two copies of `C` (rows and
//! columns) before; on the MNI152 demo a two-level cycle went from 5.0–5.9 to 3.2–3.6 ms
//! (timed inside the cycle, same GMRES iterations).

use bs_mesh::Vector3;
use rayon::prelude::*;

use crate::kernels::simd::{BlockOp, Lanes, dispatch};
use crate::linalg::nodal::NodalMatrix;
use crate::linalg::sparse::{RankOneSum, RankOneSum32, batch_chunks, split_rows};

/// Nodes per rayon task of the passes.
const ROWS: usize = 2048;

/// `K₀` fused (see the module documentation).
#[derive(Debug, Clone)]
pub(crate) struct Operator32 {
    ptr: Vec<u32>,
    col: Vec<u32>,
    /// Per slot `(r, c)`: row `i` of `[E_rc | (c_c)_r]`.
    rows: Vec<[[f32; 4]; 3]>,
    /// Per slot `(r, c)`: `(c_r)_c` with lane 3 zero (empty without nodal terms).
    proj: Vec<[f32; 4]>,
    /// `w_r` of node `r`'s term (empty without nodal terms).
    weight: Vec<f64>,
    /// The terms that are not a node's own, numbered from zero.
    extra: Option<RankOneSum32>,
}

/// Scratch of [`Operator32::apply_with`].
#[derive(Debug, Clone)]
pub(crate) struct OperatorScratch {
    /// `x̂ = (x, s)` per node.
    xs: Vec<[f64; 4]>,
    /// `s` of the extra terms.
    extra: Vec<f64>,
}

/// Scratch of [`Operator32::apply_batch`]: `x̂` of the `K` vectors side by side per node, so
/// that one gather of a column serves all of them.
#[derive(Debug, Clone)]
pub(crate) struct BatchScratch<const K: usize> {
    xs: Vec<[[f64; 4]; K]>,
    extra: [Vec<f64>; K],
}

impl Operator32 {
    /// The fused single-precision form of `k`.
    pub(crate) fn new(k: &NodalMatrix) -> Self {
        let e = &k.assembled;
        let n = e.rows();
        let mut rows: Vec<[[f32; 4]; 3]> = e
            .val
            .par_iter()
            .map(|m| {
                std::array::from_fn(|i| [m[(i, 0)] as f32, m[(i, 1)] as f32, m[(i, 2)] as f32, 0.0])
            })
            .collect();
        let (ptr, col) = (e.ptr.clone(), e.col.clone());
        let Some(nodal) = &k.nodal else {
            return Operator32 {
                ptr,
                col,
                rows,
                proj: Vec::new(),
                weight: Vec::new(),
                extra: None,
            };
        };
        // A node's own term fits when its support lies in the node's row of E.
        let fits: Vec<bool> = (0..nodal.terms())
            .into_par_iter()
            .map(|t| {
                let (lo, hi) = (nodal.c_ptr[t] as usize, nodal.c_ptr[t + 1] as usize);
                t < n && nodal.c_col[lo..hi].iter().all(|&m| e.find(t, m as usize).is_some())
            })
            .collect();
        let f32s = |v: &Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
        // Row t of C into the slots of row t.
        let mut proj = vec![[0.0f32; 4]; col.len()];
        let mut slots = split_rows(&ptr, &mut proj);
        slots.par_iter_mut().enumerate().with_min_len(256).filter(|(t, _)| fits[*t]).for_each(
            |(t, row)| {
                let (lo, hi) = (nodal.c_ptr[t] as usize, nodal.c_ptr[t + 1] as usize);
                for (&m, v) in nodal.c_col[lo..hi].iter().zip(&nodal.c_val[lo..hi]) {
                    let k = e.find(t, m as usize).expect("checked by fits") - ptr[t] as usize;
                    let [x, y, z] = f32s(v);
                    row[k] = [x, y, z, 0.0];
                }
            },
        );
        // Row m of Cᵀ into lane 3 of the slots of row m.
        let mut slots = split_rows(&ptr, &mut rows);
        slots.par_iter_mut().enumerate().with_min_len(256).for_each(|(m, row)| {
            let (lo, hi) = (nodal.t_ptr[m] as usize, nodal.t_ptr[m + 1] as usize);
            for (&t, v) in nodal.t_col[lo..hi].iter().zip(&nodal.t_val[lo..hi]) {
                if fits[t as usize] {
                    let k =
                        e.find(m, t as usize).expect("the pattern is symmetric") - ptr[m] as usize;
                    let v = f32s(v);
                    for (i, r) in row[k].iter_mut().enumerate() {
                        r[3] = v[i];
                    }
                }
            }
        });
        let weight = (0..n).map(|t| if fits[t] { nodal.weight[t] } else { 0.0 }).collect();
        let extra_terms: Vec<usize> = (0..nodal.terms()).filter(|&t| !fits[t]).collect();
        let extra = (!extra_terms.is_empty()).then(|| extra_sum(nodal, &extra_terms, n));
        Operator32 { ptr, col, rows, proj, weight, extra }
    }

    /// Bytes one [`apply_with`](Self::apply_with) reads and writes: the slots of both
    /// passes, the offsets, the nodal weights, `x̂` written and read once per node and
    /// gathered once per slot (from cache: counted once), the output (the extra terms
    /// left out: a few per cent of the nodes).
    pub(crate) fn bytes(&self) -> usize {
        let n = self.ptr.len() - 1;
        let slots = self.col.len();
        let matrix = slots * (std::mem::size_of::<[[f32; 4]; 3]>() + 4)
            + self.proj.len() * std::mem::size_of::<[f32; 4]>()
            + self.weight.len() * 8
            + (n + 1) * 4;
        // x read, x̂ written and read, the output written.
        matrix + n * (24 + 32 + 32 + 24)
    }

    /// Scratch buffers for [`apply_with`](Self::apply_with).
    pub(crate) fn scratch(&self) -> OperatorScratch {
        OperatorScratch {
            xs: vec![[0.0; 4]; self.ptr.len() - 1],
            extra: vec![0.0; self.extra.as_ref().map_or(0, RankOneSum32::terms)],
        }
    }

    /// Scratch buffers for [`apply_batch`](Self::apply_batch).
    pub(crate) fn batch_scratch<const K: usize>(&self) -> BatchScratch<K> {
        let terms = self.extra.as_ref().map_or(0, RankOneSum32::terms);
        BatchScratch {
            xs: vec![[[0.0; 4]; K]; self.ptr.len() - 1],
            extra: std::array::from_fn(|_| vec![0.0; terms]),
        }
    }

    /// `then(j, a, out_j_a, (K₀ x_j)_a)` for every vector `j` and node `a`: the `K` products
    /// of [`apply_with`](Self::apply_with) in one pass over the slots (each slot read once
    /// for all of them, the product's cost being the slots' bytes).
    pub(crate) fn apply_batch<const K: usize>(
        &self,
        x: [&[Vector3<f64>]; K],
        s: &mut BatchScratch<K>,
        out: [&mut [Vector3<f64>]; K],
        then: impl Fn(usize, usize, &mut Vector3<f64>, Vector3<f64>) + Sync,
    ) {
        s.xs.par_chunks_mut(ROWS).enumerate().for_each(|(k, chunk)| {
            dispatch(ProjectBatch { op: self, x, out: chunk, start: k * ROWS })
        });
        if let Some(extra) = &self.extra {
            for (xj, sj) in x.iter().zip(s.extra.iter_mut()) {
                extra.project_into(xj, sj);
            }
        }
        let tasks = batch_chunks(out, ROWS);
        let (xs, terms, then) = (&s.xs[..], &s.extra, &then);
        tasks.into_par_iter().enumerate().for_each(|(k, out)| {
            dispatch(MultiplyBatch { op: self, xs, terms, out, start: k * ROWS, then })
        });
    }

    /// `then(a, out_a, (K₀ x)_a)` for every node `a`.
    pub(crate) fn apply_with(
        &self,
        x: &[Vector3<f64>],
        s: &mut OperatorScratch,
        out: &mut [Vector3<f64>],
        then: impl Fn(usize, &mut Vector3<f64>, Vector3<f64>) + Sync,
    ) {
        s.xs.par_chunks_mut(ROWS)
            .enumerate()
            .for_each(|(k, chunk)| dispatch(Project { op: self, x, out: chunk, start: k * ROWS }));
        if let Some(extra) = &self.extra {
            extra.project_into(x, &mut s.extra);
        }
        let (xs, terms, then) = (&s.xs[..], &s.extra[..], &then);
        out.par_chunks_mut(ROWS).enumerate().for_each(|(k, chunk)| {
            dispatch(Multiply { op: self, xs, terms, out: chunk, start: k * ROWS, then })
        });
    }
}

/// The terms `ts` of `nodal` as a sum of their own, renumbered from zero.
fn extra_sum(nodal: &RankOneSum, ts: &[usize], nodes: usize) -> RankOneSum32 {
    let rows: Vec<Vec<(u32, Vector3<f64>)>> = ts
        .iter()
        .map(|&t| {
            let (lo, hi) = (nodal.c_ptr[t] as usize, nodal.c_ptr[t + 1] as usize);
            nodal.c_col[lo..hi].iter().copied().zip(nodal.c_val[lo..hi].iter().copied()).collect()
        })
        .collect();
    let weight = ts.iter().map(|&t| nodal.weight[t]).collect();
    RankOneSum32::from(&RankOneSum::new(weight, &rows, nodes))
}

/// Pass one on a chunk of nodes: `x̂_r = (x_r, w_r c_r·x)`.
struct Project<'a> {
    op: &'a Operator32,
    x: &'a [Vector3<f64>],
    out: &'a mut [[f64; 4]],
    start: usize,
}

impl BlockOp for Project<'_> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lanes>(self, l: L) {
        let op = self.op;
        for (i, o) in self.out.iter_mut().enumerate() {
            let r = self.start + i;
            let v = self.x[r];
            let s = if op.weight.is_empty() {
                0.0
            } else {
                let (lo, hi) = (op.ptr[r] as usize, op.ptr[r + 1] as usize);
                let mut acc = l.splat(0.0);
                for (c, &m) in op.proj[lo..hi].iter().zip(&op.col[lo..hi]) {
                    let y = &self.x[m as usize];
                    acc = l.mul_add(l.load_f32(*c), l.load([y.x, y.y, y.z, 0.0]), acc);
                }
                let a = l.store(acc);
                op.weight[r] * (a[0] + a[1] + a[2])
            };
            *o = [v.x, v.y, v.z, s];
        }
    }
}

/// Pass two on a chunk of rows: `Σ_c [E_rc | (c_c)_r] x̂_c` (+ the extra terms), each value
/// landing in its output through `then`.
struct Multiply<'a, F> {
    op: &'a Operator32,
    xs: &'a [[f64; 4]],
    terms: &'a [f64],
    out: &'a mut [Vector3<f64>],
    start: usize,
    then: &'a F,
}

impl<F: Fn(usize, &mut Vector3<f64>, Vector3<f64>)> BlockOp for Multiply<'_, F> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lanes>(self, l: L) {
        let op = self.op;
        for (i, o) in self.out.iter_mut().enumerate() {
            let r = self.start + i;
            let (lo, hi) = (op.ptr[r] as usize, op.ptr[r + 1] as usize);
            let zero = l.splat(0.0);
            let (mut a0, mut a1, mut a2) = (zero, zero, zero);
            for (m, &c) in op.rows[lo..hi].iter().zip(&op.col[lo..hi]) {
                let x = l.load(self.xs[c as usize]);
                a0 = l.mul_add(l.load_f32(m[0]), x, a0);
                a1 = l.mul_add(l.load_f32(m[1]), x, a1);
                a2 = l.mul_add(l.load_f32(m[2]), x, a2);
            }
            // Lane k of the sum of the transposed accumulators is row k's dot product.
            let t = l.transpose([a0, a1, a2, zero]);
            let mut acc = l.add(l.add(t[0], t[1]), l.add(t[2], t[3]));
            if let Some(extra) = &op.extra {
                acc = extra.expand_row_lanes(l, r, self.terms, acc);
            }
            let v = l.store(acc);
            (self.then)(r, o, Vector3::new(v[0], v[1], v[2]));
        }
    }
}

/// Pass one of [`Operator32::apply_batch`] on a chunk of nodes: `x̂_jr = (x_jr, w_r c_r·x_j)`.
struct ProjectBatch<'a, const K: usize> {
    op: &'a Operator32,
    x: [&'a [Vector3<f64>]; K],
    out: &'a mut [[[f64; 4]; K]],
    start: usize,
}

impl<const K: usize> BlockOp for ProjectBatch<'_, K> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lanes>(self, l: L) {
        let op = self.op;
        for (i, o) in self.out.iter_mut().enumerate() {
            let r = self.start + i;
            let mut acc = [l.splat(0.0); K];
            if !op.weight.is_empty() {
                let (lo, hi) = (op.ptr[r] as usize, op.ptr[r + 1] as usize);
                for (c, &m) in op.proj[lo..hi].iter().zip(&op.col[lo..hi]) {
                    let c = l.load_f32(*c);
                    for j in 0..K {
                        let y = &self.x[j][m as usize];
                        acc[j] = l.mul_add(c, l.load([y.x, y.y, y.z, 0.0]), acc[j]);
                    }
                }
            }
            for j in 0..K {
                let v = self.x[j][r];
                let s = if op.weight.is_empty() {
                    0.0
                } else {
                    let a = l.store(acc[j]);
                    op.weight[r] * (a[0] + a[1] + a[2])
                };
                o[j] = [v.x, v.y, v.z, s];
            }
        }
    }
}

/// Pass two of [`Operator32::apply_batch`] on a chunk of rows.
struct MultiplyBatch<'a, F, const K: usize> {
    op: &'a Operator32,
    xs: &'a [[[f64; 4]; K]],
    terms: &'a [Vec<f64>; K],
    out: [&'a mut [Vector3<f64>]; K],
    start: usize,
    then: &'a F,
}

impl<F: Fn(usize, usize, &mut Vector3<f64>, Vector3<f64>), const K: usize> BlockOp
    for MultiplyBatch<'_, F, K>
{
    type Output = ();
    #[inline(always)]
    fn run<L: Lanes>(self, l: L) {
        let op = self.op;
        let out = self.out;
        let len = out[0].len();
        for i in 0..len {
            let r = self.start + i;
            let (lo, hi) = (op.ptr[r] as usize, op.ptr[r + 1] as usize);
            let zero = l.splat(0.0);
            let mut a = [[zero; 3]; K];
            for (m, &c) in op.rows[lo..hi].iter().zip(&op.col[lo..hi]) {
                let (m0, m1, m2) = (l.load_f32(m[0]), l.load_f32(m[1]), l.load_f32(m[2]));
                let xc = &self.xs[c as usize];
                for j in 0..K {
                    let x = l.load(xc[j]);
                    a[j][0] = l.mul_add(m0, x, a[j][0]);
                    a[j][1] = l.mul_add(m1, x, a[j][1]);
                    a[j][2] = l.mul_add(m2, x, a[j][2]);
                }
            }
            for j in 0..K {
                let t = l.transpose([a[j][0], a[j][1], a[j][2], zero]);
                let mut acc = l.add(l.add(t[0], t[1]), l.add(t[2], t[3]));
                if let Some(extra) = &op.extra {
                    acc = extra.expand_row_lanes(l, r, &self.terms[j], acc);
                }
                let v = l.store(acc);
                (self.then)(j, r, &mut out[j][i], Vector3::new(v[0], v[1], v[2]));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::sparse::BlockCsr;
    use crate::{Model, ModelOptions, Solid, TetFormulation};
    use bs_material::Material;
    use bs_mesh::structured::box_mesh;

    /// The fused product against the double-precision `E x + Cᵀ W C x` of the same matrix,
    /// within single-precision rounding of the entries (relative 2⁻²⁴ each; the sums of
    /// ~30 terms per row stay below 1e-6 of the row's magnitude `Σ |K_rc| |x_c|`).
    fn check(k: &NodalMatrix) {
        let n = k.assembled.rows();
        let x: Vec<Vector3<f64>> = (0..n)
            .map(|i| {
                let t = i as f64;
                Vector3::new((0.7 * t).sin(), (1.3 * t).cos(), 0.5 - (i % 3) as f64 * 0.4)
            })
            .collect();
        let mut expect = vec![Vector3::zeros(); n];
        k.mul(&x, &mut expect, &mut k.scratch());
        let op = Operator32::new(k);
        let mut s = op.scratch();
        let mut got = vec![Vector3::zeros(); n];
        op.apply_with(&x, &mut s, &mut got, |_, o, y| *o = y);
        // Magnitude of each row's sum, for the relative bound.
        let mut abs = vec![Vector3::zeros(); n];
        let absx: Vec<Vector3<f64>> = x.iter().map(|v| v.abs()).collect();
        let absk = NodalMatrix {
            assembled: BlockCsr {
                ptr: k.assembled.ptr.clone(),
                col: k.assembled.col.clone(),
                val: k.assembled.val.iter().map(|m| m.abs()).collect(),
            },
            nodal: k.nodal.as_ref().map(|r| RankOneSum {
                c_val: r.c_val.iter().map(|v| v.abs()).collect(),
                t_val: r.t_val.iter().map(|v| v.abs()).collect(),
                ..r.clone()
            }),
            ratio: k.ratio.clone(),
        };
        absk.mul(&absx, &mut abs, &mut absk.scratch());
        for a in 0..n {
            let err = (got[a] - expect[a]).amax();
            assert!(err <= 1e-6 * abs[a].amax(), "node {a}: {err:e} against {:e}", abs[a].amax());
        }
        // The batch of three (x, 2x − 1, and zero) gives each vector's single product, to
        // the last bit: the same sums in the same order.
        let x2: Vec<Vector3<f64>> = x.iter().map(|v| v * 2.0 - Vector3::repeat(1.0)).collect();
        let zero = vec![Vector3::zeros(); n];
        let mut one2 = vec![Vector3::zeros(); n];
        op.apply_with(&x2, &mut s, &mut one2, |_, o, y| *o = y);
        let mut b =
            [vec![Vector3::zeros(); n], vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]];
        let [b0, b1, b2] = &mut b;
        let mut bs = op.batch_scratch::<3>();
        op.apply_batch([&x, &x2, &zero], &mut bs, [b0, b1, b2], |_, _, o, y| *o = y);
        assert_eq!(b[0], got);
        assert_eq!(b[1], one2);
        assert!(b[2].iter().all(|v| *v == Vector3::zeros()));
    }

    fn model(tet: TetFormulation, two_solids: bool) -> Model {
        let mesh = box_mesh(4, 1.0, true);
        let soft =
            Solid { material: Material::neo_hookean(3000.0, 0.49).unwrap(), density: 1000.0 };
        let stiff =
            Solid { material: Material::neo_hookean(9000.0, 0.45).unwrap(), density: 1000.0 };
        let solids: Vec<usize> = mesh
            .elements
            .iter()
            .map(|e| {
                let x = e.nodes().iter().map(|&a| mesh.nodes[a].x).sum::<f64>() / 4.0;
                usize::from(two_solids && x > 0.5)
            })
            .collect();
        Model::new(&mesh, &[soft, stiff], &solids, ModelOptions { tet, hourglass: 0.1 }).unwrap()
    }

    #[test]
    fn the_fused_product_equals_the_double_precision_one() {
        for tet in [TetFormulation::T4, TetFormulation::T4Anp] {
            check(&model(tet, false).linear_stiffness());
        }
    }

    #[test]
    fn terms_shared_by_two_solids_are_carried_apart() {
        let k = model(TetFormulation::T4Anp, true).linear_stiffness();
        let op = Operator32::new(&k);
        assert!(op.extra.as_ref().is_some_and(|e| e.terms() > 0));
        check(&k);
    }
}
