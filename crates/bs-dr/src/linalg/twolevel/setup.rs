//! Building the preconditioner: the projected diagonal inverses, `λ_max(D⁻¹K₀)` by the power
//! method, the tentative and smoothed prolongators, the Galerkin coarse factor and the
//! single-precision operator of the smoother; and the constraints of a solve.

use bs_mesh::{Point3, Vector3};
use faer::sparse::SparseColMat;
use nalgebra::Matrix3;
use rayon::prelude::*;

use std::sync::Arc;

use super::coarse::{Coarse, galerkin, tentative_prolongator};
use super::constraints::Constraints;
use super::correction::corrected;
use super::operator::Operator32;
use super::params::{TwoLevelError, TwoLevelParams};
use super::projector::{Projector, projected_inverse};
use super::rows::{NodeRows, NodeRows32, product, tentative_columns, transpose};
use super::split::{VolumetricSplit, split};
use crate::linalg::nodal::{NodalMatrix, NodalScratch};
use crate::linalg::sparse::max_abs;

/// The two-level preconditioner of `K₀` (see the module documentation).
#[derive(Debug)]
pub struct TwoLevel {
    /// The 3×3 diagonal blocks of `K₀` (both parts); `K₀` itself is not kept.
    pub(super) diag: Vec<Matrix3<f64>>,
    /// `K₀` in single precision: the operator of the smoother.
    pub(super) op32: Operator32,
    pub(super) params: TwoLevelParams,
    /// The constraints it was built with (the fixed components).
    pub(super) fixed: Constraints,
    /// `λ_max(D⁻¹ K₀)` with a 10% margin.
    pub(super) lambda_max: f64,
    pub(super) p: NodeRows32,
    /// `Pᵀ`: per coarse column, `(node, 3-vector)`.
    pub(super) pt: NodeRows32,
    pub(super) coarse: Coarse,
    /// What [`constrain_coarse`](Self::constrain_coarse) needs, when
    /// [`TwoLevelParams::contact_coarse`] asked to keep it.
    pub(super) retained: Option<Retained>,
    /// The nearly incompressible split, when `K₀` asked for it ([`super::split`]), with the
    /// preconditioner of its block.
    pub(super) split: Option<Box<(VolumetricSplit, TwoLevel)>>,
}

/// [`TwoLevel::constrain_coarse`] builds a coarse matrix for the first constraints that hold
/// nodes and rebuilds it only when more nodes changed their constraints since than are held
/// (a contact set that turned over). Measured on the MNI152 demo's `cargo xtask bench
/// update` (warm updates at 4–8 mm, GMRES iterations, coarse builds over the 16 solves of
/// the bench): rebuilt at 10 % changed 194 GMRES / 36 builds, at 30 % 181 / 36, this rule
/// 177 / 19; without it 246.
const STALE_FRACTION: f64 = 1.0;

/// Fewer changed nodes than this never build: a few held nodes barely change the coarse
/// problem, and a build costs about as much as five GMRES iterations (the bench: 181 GMRES
/// and 18 builds against 177 and 19 with a minimum of 8).
const STALE_MIN: usize = 50;

/// The contact set's coarse matrix is kept only while its factor has at most this many
/// nonzeros per scalar nonzero of `K₀`'s element part: a build refactorises it, and the
/// factor's cost grows faster than the mesh. Measured (nonzeros of the factor per nonzero
/// of `K₀`, time of a build, Newton / GMRES iterations of the cold solve without and with
/// the kept matrices): MNI152 coarse mesh 0.25, 12 / 74 → 12 / 56; demo 0.33, 15–45 ms,
/// 14 / 78 → 13 / 51; fine 0.41, 12 / 83 → 12 / 60; the 852k-tet brain 0.94–1.0, 0.9–1.5 s
/// (ten GMRES iterations there), 14 / 117 → 16 / 196 (a coarse matrix built for a contact
/// set that then moved on; rebuilt whenever a quarter of the held nodes changed, 13 / 96
/// but six builds); the ellipsoid's rim mesh 0.87–0.90 (not kept).
const CONTACT_COARSE_FILL: f64 = 0.5;

/// `K₀`, the prolongator, `K₀ P` (double precision) and the assembled `Pᵀ K₀ P`, kept
/// after the setup.
#[derive(Debug)]
pub(super) struct Retained {
    pub(super) k: NodalMatrix,
    pub(super) p: NodeRows,
    pub(super) kp: NodeRows,
    /// `Pᵀ K₀ P`, lower triangle (the pattern of the setup's symbolic factor).
    pub(super) galerkin: SparseColMat<usize, f64>,
}

impl TwoLevel {
    /// Builds the preconditioner of `k` (`K₀`) on the nodes at `x`, whose mean element
    /// edge is `mean_edge` (the aggregates are `params.aggregate_size` of them across), with
    /// the nodal constraints `fixed` (the prescribed components).
    pub fn new(
        k: NodalMatrix,
        x: &[Point3<f64>],
        mean_edge: f64,
        fixed: &Projector,
        params: TwoLevelParams,
    ) -> Result<Self, TwoLevelError> {
        let n = x.len();
        let split = match split(&k, params.split_above) {
            Some((block, split)) => {
                let block_params =
                    TwoLevelParams { split_above: f64::INFINITY, contact_coarse: false, ..params };
                let block = TwoLevel::new(block, x, mean_edge, fixed, block_params)?;
                Some(Box::new((split, block)))
            }
            None => None,
        };
        let diag: Vec<Matrix3<f64>> = (0..n).into_par_iter().map(|a| k.diagonal(a)).collect();
        let inv_diag: Vec<Matrix3<f64>> =
            (0..n).into_par_iter().map(|a| projected_inverse(&diag[a], &fixed.matrix[a])).collect();
        let mut scratch = k.scratch();
        let lambda_max = 1.1 * power_max(&k, &inv_diag, fixed, &mut scratch, 20);
        let h = params.aggregate_size * mean_edge;
        let tentative = tentative_prolongator(x, fixed, h);
        let omega = 4.0 / (3.0 * lambda_max);
        // Smoothed with the whole of K₀, its nodal volumetric term included (textbook
        // smoothed aggregation: ω from λ_max of the same D⁻¹K₀), so that the coarse basis
        // feels the volumetric stiffness. P's support widens from the one-ring to the
        // two-ring; measured on the MNI152 demo against smoothing with the element part
        // only: 81 GMRES iterations instead of 99 at 8 mm, 142 instead of 161 at 20 mm, 972
        // instead of 1501 at ν = 0.499, 183 instead of 208 on the 852k-tet brain; the
        // preparation 0.08 s longer (1.1 s on the 852k-tet brain), the solves shorter.
        let kp = product(&k.assembled, k.nodal.as_ref(), &tentative);
        let p = smooth(&tentative, &kp, &inv_diag, omega);
        let nc = tentative_columns(&tentative);
        let pt = transpose(&p, nc);
        let kp = product(&k.assembled, k.nodal.as_ref(), &p);
        let g = galerkin(&pt, &kp, nc)?;
        let fixed = Constraints {
            projector: fixed.clone(),
            inv_diag,
            coarse: None,
            coarse_for: Vec::new(),
        };
        let op32 = Operator32::new(&k);
        let (p32, pt32) = (p.to_f32(), pt.to_f32());
        let coarse = g.factor;
        // The mixed form's solves use the block's preconditioner, whose coarse matrix stays
        // the setup's: building one for the contact set there was measured worse (MNI152 at
        // ν = 0.499: 25 Newton / 199 GMRES iterations against 16 / 162).
        let fill = coarse.values.len() as f64 / (9 * k.assembled.col.len()) as f64;
        let keep = params.contact_coarse && split.is_none() && fill <= CONTACT_COARSE_FILL;
        let retained = keep.then_some(Retained { k, p, kp, galerkin: g.matrix });
        Ok(TwoLevel {
            diag,
            op32,
            params,
            fixed,
            lambda_max,
            p: p32,
            pt: pt32,
            coarse,
            retained,
            split,
        })
    }

    /// The nearly incompressible split the solves may use with this preconditioner, if
    /// any, and the preconditioner of its block.
    pub fn split(&self) -> Option<(&VolumetricSplit, &TwoLevel)> {
        self.split.as_deref().map(|(s, b)| (s, b))
    }

    /// Constraints of this preconditioner with the projector of `con` (another
    /// preconditioner's constraints on the same nodes), its setup's coarse factor.
    pub fn constraints_like(&self, con: &Constraints) -> Constraints {
        let inv_diag = (0..self.diag.len())
            .into_par_iter()
            .map(|a| projected_inverse(&self.diag[a], &con.projector.matrix[a]))
            .collect();
        Constraints {
            projector: con.projector.clone(),
            inv_diag,
            coarse: None,
            coarse_for: Vec::new(),
        }
    }

    /// The 3×3 diagonal block of node `a` of the linearised stiffness the preconditioner
    /// approximates.
    pub fn diagonal(&self, a: usize) -> Matrix3<f64> {
        self.diag[a]
    }

    /// Keeps the coarse factor of `con` that of `Pᵀ Π K₀ Π P` for its constraints (the fixed
    /// components and the contact normals of held nodes), when the matrices were kept
    /// ([`TwoLevelParams::contact_coarse`]): built for the first constraints that hold at
    /// least [`STALE_MIN`] nodes, rebuilt when they differ from the ones it was built for at
    /// more nodes than are held ([`STALE_FRACTION`]), back to the setup's when no node is
    /// held. Returns whether it built one.
    ///
    /// The setup's coarse matrix knows only the fixed components: with nodes held on the
    /// skull its correction is not the Galerkin one of the constrained operator, and GMRES
    /// needs more iterations (the MNI152 demo's warm updates at 4–8 mm: 189 against 246
    /// GMRES iterations). Only the rows of the held nodes change: `P_Π = P + E`,
    /// `E = (Π − I) P` on those rows, and `K₀ P_Π = K₀ P + K₀ E`, so the product is local;
    /// so is the Galerkin correction (`correction`), factorised on the setup's symbolic
    /// factor: 10–14 ms on the demo, 35–45 ms with the whole Galerkin sum and a new
    /// ordering. A failed factor falls back to the setup's.
    pub fn constrain_coarse(&self, con: &mut Constraints) -> bool {
        let Some(r) = &self.retained else { return false };
        let (pi, base) = (&con.projector, &self.fixed.projector);
        let n = r.p.rows();
        let held = |a: usize| pi.constrained[a] && pi.matrix[a] != base.matrix[a];
        let built_for = |a: usize| con.coarse_for.get(a).unwrap_or(&base.matrix[a]);
        let (held_count, stale) = (0..n)
            .into_par_iter()
            .with_min_len(1024)
            .map(|a| (usize::from(held(a)), usize::from(pi.matrix[a] != *built_for(a))))
            .reduce(|| (0, 0), |x, y| (x.0 + y.0, x.1 + y.1));
        if held_count == 0 {
            con.coarse = None;
            con.coarse_for.clear();
            return false;
        }
        let first = con.coarse_for.is_empty();
        if stale < STALE_MIN || (!first && (stale as f64) <= STALE_FRACTION * held_count as f64) {
            return false;
        }
        let e: Vec<Vec<(u32, Vector3<f64>)>> = (0..n)
            .into_par_iter()
            .with_min_len(1024)
            .map(|a| {
                if !held(a) {
                    return Vec::new();
                }
                let (cols, vals) = r.p.row(a);
                cols.iter().zip(vals).map(|(&j, v)| (j, pi.matrix[a] * v - v)).collect()
            })
            .collect();
        let e = NodeRows::from_rows(e);
        let ke = product(&r.k.assembled, r.k.nodal.as_ref(), &e);
        // A failed factor leaves the setup's, and is not tried again for these constraints.
        con.coarse =
            corrected(&r.galerkin, &self.coarse.symbolic, &e, &r.kp, &ke).ok().map(Arc::new);
        con.coarse_for.clone_from(&pi.matrix);
        con.coarse.is_some()
    }

    /// Number of coarse unknowns.
    pub fn coarse_size(&self) -> usize {
        self.pt.rows()
    }

    /// The constraints the preconditioner was built with (the fixed components): the start
    /// of every solve.
    pub fn constraints(&self) -> Constraints {
        self.fixed.clone()
    }

    /// Constrains node `a` along the directions `dirs` in addition to its fixed components
    /// (an empty `dirs` restores the fixed ones). The directions are taken orthogonal to the
    /// fixed components and orthonormalised; those that remain are written to `added`, and
    /// their number is returned (the node can move along them to meet its constraint).
    pub fn constrain(
        &self,
        c: &mut Constraints,
        a: usize,
        dirs: &[Vector3<f64>],
        added: &mut [Vector3<f64>; 3],
    ) -> usize {
        let fixed = &self.fixed.projector;
        let mut m = 0;
        for d in dirs {
            let mut v = fixed.matrix[a] * d;
            for b in &added[..m] {
                v -= b * b.dot(&v);
            }
            let nv = v.norm();
            if nv > 1e-6 && m < 3 {
                added[m] = v / nv;
                m += 1;
            }
        }
        let mut matrix = fixed.matrix[a];
        for b in &added[..m] {
            matrix -= b * b.transpose();
        }
        c.projector.matrix[a] = matrix;
        c.projector.constrained[a] = fixed.constrained[a] || m > 0;
        c.inv_diag[a] =
            if m == 0 { self.fixed.inv_diag[a] } else { projected_inverse(&self.diag[a], &matrix) };
        m
    }

    /// Sizes for benchmarks and profiles: (coarse unknowns, nonzeros of the coarse factor,
    /// nonzeros of the prolongator as 3-vectors).
    pub fn sizes(&self) -> (usize, usize, usize) {
        (self.pt.rows(), self.coarse.values.len(), self.p.len())
    }
}

/// The smoothed prolongator `P = (I − ω D⁻¹ K₀) P_tent` from `P_tent` and `K₀ P_tent`
/// (row by row, columns merged in increasing order).
fn smooth(tentative: &NodeRows, kp: &NodeRows, inv_diag: &[Matrix3<f64>], omega: f64) -> NodeRows {
    let n = inv_diag.len();
    NodeRows::from_rows(
        (0..n)
            .into_par_iter()
            .with_min_len(256)
            .map(|a| {
                let (c0, v0) = tentative.row(a);
                let (c1, v1) = kp.row(a);
                let m = inv_diag[a] * omega;
                let mut out: Vec<(u32, Vector3<f64>)> = Vec::with_capacity(c0.len() + c1.len());
                let (mut i, mut j) = (0, 0);
                while i < c0.len() || j < c1.len() {
                    if j == c1.len() || (i < c0.len() && c0[i] < c1[j]) {
                        out.push((c0[i], v0[i]));
                        i += 1;
                    } else if i == c0.len() || c1[j] < c0[i] {
                        out.push((c1[j], -(m * v1[j])));
                        j += 1;
                    } else {
                        out.push((c0[i], v0[i] - m * v1[j]));
                        i += 1;
                        j += 1;
                    }
                }
                out
            })
            .collect(),
    )
}

/// Largest eigenvalue of `D⁻¹ Π K₀ Π` by the power method (deterministic start).
fn power_max(
    k: &NodalMatrix,
    inv_diag: &[Matrix3<f64>],
    pi: &Projector,
    s: &mut NodalScratch,
    iterations: usize,
) -> f64 {
    let n = inv_diag.len();
    let mut x: Vec<Vector3<f64>> = (0..n)
        .map(|a| {
            let t = a as f64;
            Vector3::new(
                1.0 + 0.5 * (0.37 * t).sin(),
                1.0 + 0.5 * (0.73 * t).cos(),
                1.0 + 0.5 * (1.1 * t).sin(),
            )
        })
        .collect();
    pi.apply(&mut x);
    let mut y = vec![Vector3::zeros(); n];
    let mut lambda = 0.0;
    for _ in 0..iterations {
        let m = max_abs(&x);
        if m == 0.0 {
            return 1.0;
        }
        x.iter_mut().for_each(|v| *v /= m);
        k.mul(&x, &mut y, s);
        pi.apply(&mut y);
        y.par_iter_mut().enumerate().for_each(|(a, v)| *v = inv_diag[a] * *v);
        // Rayleigh quotient in the D-inner product: (x, D⁻¹A x)_D = xᵀ A x / xᵀ D x.
        lambda = max_abs(&y);
        std::mem::swap(&mut x, &mut y);
    }
    lambda
}
