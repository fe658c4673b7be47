//! Building the preconditioner: the mesh level (diagonal blocks and their projected
//! inverses, `λ_max(D⁻¹K)` by the power method, the fused single-precision operator of the
//! smoother), the mesh's aggregates and smoothed prolongator, the Galerkin operator of
//! level 1 and the coarse levels below it; and the constraints of a solve.

use bs_mesh::{Point3, Vector3};
use nalgebra::Matrix3;
use rayon::prelude::*;
use std::sync::Arc;

use super::blocks::Blocks;
use super::constraints::{Built, Constraints};
use super::levels::CoarseStructure;
use super::operator::Operator32;
use super::params::{MultilevelError, MultilevelParams};
use super::products::{FineP, LevelPatterns, fine_times, smooth};
use super::projector::{Projector, projected_inverse};
use super::split::{VolumetricSplit, split};
use super::tentative::{Aggregates, Matrix6, rigid_modes, tentative};
use crate::linalg::nodal::NodalMatrix;
use crate::linalg::sparse::max_abs;

/// The multilevel preconditioner of the stiffness (see the module documentation).
#[derive(Debug)]
pub struct Multilevel {
    /// The 3×3 diagonal blocks of the operator (both parts).
    pub(super) diag: Vec<Matrix3<f64>>,
    /// The operator in single precision: the smoother's.
    pub(super) op32: Operator32,
    pub(super) params: MultilevelParams,
    /// The constraints it was built with (the fixed components).
    pub(super) fixed: Constraints,
    /// `λ_max(D⁻¹ K)` with a 10% margin.
    pub(super) lambda_max: f64,
    /// The power method's last iterate (the start of a rebuild's).
    pub(super) eigenvector: Vec<Vector3<f64>>,
    /// The prolongators and patterns, shared by every rebuild.
    pub(super) structure: Arc<Structure>,
    /// The coarse levels' numbers, and the constraints they were built for (the fixed
    /// components at the setup; those of the solve at a rebuild).
    pub(super) levels: Built,
    /// The operator, kept for the contact set's coarse levels when
    /// [`MultilevelParams::contact_coarse`] asked for it.
    pub(super) retained: Option<NodalMatrix>,
    /// The nearly incompressible split, when the operator asked for it ([`super::split`]),
    /// with the preconditioner of its block.
    pub(super) split: Option<Box<(VolumetricSplit, Multilevel)>>,
}

/// What depends only on the mesh, the fixed components and the setup's operator: the mesh's
/// smoothed prolongator (double precision for the products, single for the cycle), its
/// transpose, the patterns of level 1 and the coarse levels' structure. A rebuild on
/// another operator of the same sparsity ([`Multilevel::rebuilt`]) reuses all of it.
#[derive(Debug)]
pub(crate) struct Structure {
    pub(super) p: FineP,
    pub(super) pt: Blocks<f64, 6, 3>,
    /// Per block of `pt`, its block in `p`.
    pub(super) pt_source: Vec<u32>,
    pub(super) p32: Blocks<f32, 3, 6>,
    pub(super) pt32: Blocks<f32, 6, 3>,
    pub(super) fine: LevelPatterns,
    pub(super) coarse: CoarseStructure,
}

/// Power-method iterations for `λ_max` of the mesh level.
const POWER_ITERATIONS: usize = 20;

/// Power-method iterations of a rebuild, from the last iterate of the one it rebuilds (the
/// largest eigenvalue of the operator moves little between two configurations).
pub(super) const REBUILD_POWER_ITERATIONS: usize = 6;

impl Multilevel {
    /// Builds the preconditioner of `k` on the nodes at `x`, whose mean element edge is
    /// `mean_edge` (the mesh's aggregates are `params.aggregate_size` of them across), with
    /// the nodal constraints `fixed` (the prescribed components).
    pub fn new(
        k: NodalMatrix,
        x: &[Point3<f64>],
        mean_edge: f64,
        fixed: &Projector,
        params: MultilevelParams,
    ) -> Result<Self, MultilevelError> {
        let n = x.len();
        let split = match split(&k, params.split_above) {
            Some((block, split)) => {
                let block_params = MultilevelParams {
                    split_above: f64::INFINITY,
                    contact_coarse: false,
                    ..params
                };
                let block = Multilevel::new(block, x, mean_edge, fixed, block_params)?;
                Some(Box::new((split, block)))
            }
            None => None,
        };
        let diag: Vec<Matrix3<f64>> = (0..n).into_par_iter().map(|a| k.diagonal(a)).collect();
        let inv_diag: Vec<Matrix3<f64>> =
            (0..n).into_par_iter().map(|a| projected_inverse(&diag[a], &fixed.matrix[a])).collect();
        let mut scratch = k.scratch();
        let mut eigenvector = Vec::new();
        let mul = |x: &[Vector3<f64>], y: &mut [Vector3<f64>]| k.mul(x, y, &mut scratch);
        let lambda_max = 1.1 * power_max(mul, &inv_diag, fixed, POWER_ITERATIONS, &mut eigenvector);
        let h = params.aggregate_size * mean_edge;
        let agg = Aggregates::new(x, h);
        let nc = agg.len();
        let (t, modes) = tentative(&agg, &rigid_modes(x, &fixed.matrix));
        // Smoothed with the whole operator, its nodal volumetric term included (textbook
        // smoothed aggregation: ω from λ_max of the same D⁻¹K), so that the coarse basis
        // feels the volumetric stiffness. P's support widens from the one-ring to the
        // two-ring; measured on the MNI152 demo against smoothing with the element part
        // only: 81 GMRES iterations instead of 99 at 8 mm, 142 instead of 161 at 20 mm, 972
        // instead of 1501 at ν = 0.499, 183 instead of 208 on the 852k-tet brain.
        let omega = 4.0 / (3.0 * lambda_max);
        let p = smooth(&t, &fine_times(&k, &t, nc), &inv_diag, omega);
        let pt = p.transpose(nc);
        let fine = LevelPatterns::fine(&k, &p, nc);
        let products = fine.galerkin_fine(&k, &p, &pt);
        let a1 = products.a1.clone();
        let dropped = modes.iter().map(dropped_modes).collect();
        let (coarse, levels) = CoarseStructure::new(a1, agg.centroid, modes, dropped, h, &params)?;
        let (p32, pt32) = (p.to_f32(), pt.to_f32());
        let pt_source = p.transpose_map(nc);
        let structure = Arc::new(Structure { p, pt, pt_source, p32, pt32, fine, coarse });
        let keep = params.contact_coarse && split.is_none();
        let levels = Built {
            levels: Arc::new(levels),
            fine: keep.then(|| Arc::new(products)),
            projector: Arc::new(fixed.matrix.clone()),
            held: 0,
        };
        let fixed = Constraints { projector: fixed.clone(), inv_diag, levels: None };
        let op32 = Operator32::new(&k);
        // The mixed form's solves use the block's preconditioner, whose coarse levels stay
        // the setup's: building them for the contact set there was measured worse (MNI152
        // at ν = 0.499: 25 Newton / 199 GMRES iterations against 16 / 162).
        let retained = keep.then_some(k);
        Ok(Multilevel {
            diag,
            op32,
            params,
            fixed,
            lambda_max,
            eigenvector,
            structure,
            levels,
            retained,
            split,
        })
    }

    /// The nearly incompressible split the solves may use with this preconditioner, if
    /// any, and the preconditioner of its block.
    pub fn split(&self) -> Option<(&VolumetricSplit, &Multilevel)> {
        self.split.as_deref().map(|(s, b)| (s, b))
    }

    /// Constraints of this preconditioner with the projector of `con` (another
    /// preconditioner's constraints on the same nodes), its setup's coarse levels.
    pub fn constraints_like(&self, con: &Constraints) -> Constraints {
        let inv_diag = (0..self.diag.len())
            .into_par_iter()
            .map(|a| projected_inverse(&self.diag[a], &con.projector.matrix[a]))
            .collect();
        Constraints { projector: con.projector.clone(), inv_diag, levels: None }
    }

    /// The 3×3 diagonal block of node `a` of the linearised stiffness the preconditioner
    /// approximates.
    pub fn diagonal(&self, a: usize) -> Matrix3<f64> {
        self.diag[a]
    }

    /// The operator it was built with, when it was kept
    /// ([`MultilevelParams::contact_coarse`]).
    pub fn operator(&self) -> Option<&NodalMatrix> {
        self.retained.as_ref()
    }

    /// Unknowns of the first coarse level.
    pub fn coarse_size(&self) -> usize {
        6 * self.structure.pt.rows()
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

    /// Sizes for benchmarks and profiles: the unknowns of every coarse level (the first
    /// coarse level first, the one factorised last), the nonzeros of the coarsest factor
    /// and the blocks of the mesh's prolongator.
    pub fn sizes(&self) -> (Vec<usize>, usize, usize) {
        let mut unknowns = vec![6 * self.structure.pt.rows()];
        unknowns.extend(self.structure.coarse.links.iter().map(|l| 6 * l.pt.rows()));
        (unknowns, self.levels.levels.factor.len(), self.structure.p.len())
    }
}

/// The modes a node of level 1 lost: zero rows of its `R`.
fn dropped_modes(r: &Matrix6) -> [bool; 6] {
    std::array::from_fn(|k| r.row(k).iter().all(|&v| v == 0.0))
}

/// Largest eigenvalue of `D⁻¹ Π A Π` by the power method, `mul` the product `y = A x`: from
/// `x` (a deterministic start when empty), left there.
pub(super) fn power_max(
    mut mul: impl FnMut(&[Vector3<f64>], &mut [Vector3<f64>]),
    inv_diag: &[Matrix3<f64>],
    pi: &Projector,
    iterations: usize,
    x: &mut Vec<Vector3<f64>>,
) -> f64 {
    let n = inv_diag.len();
    if x.len() != n {
        *x = (0..n)
            .map(|a| {
                let t = a as f64;
                Vector3::new(
                    1.0 + 0.5 * (0.37 * t).sin(),
                    1.0 + 0.5 * (0.73 * t).cos(),
                    1.0 + 0.5 * (1.1 * t).sin(),
                )
            })
            .collect();
    }
    pi.apply(x);
    let mut y = vec![Vector3::zeros(); n];
    let mut lambda = 0.0;
    for _ in 0..iterations {
        let m = max_abs(x);
        if m == 0.0 {
            return 1.0;
        }
        x.iter_mut().for_each(|v| *v /= m);
        mul(x, &mut y);
        pi.apply(&mut y);
        y.par_iter_mut().enumerate().for_each(|(a, v)| *v = inv_diag[a] * *v);
        lambda = max_abs(&y);
        std::mem::swap(x, &mut y);
    }
    lambda
}
