//! The nearly incompressible split: `K₀ = E + Cᵀ W C` (T4ANP: the deviatoric element part and
//! the nodal volumetric term, [`NodalMatrix`]) solved in the mixed form
//!
//! ```text
//! [ E + Cᵀ αW C    Cᵀ ] [u]   [r]
//! [ (1−α)W C      −I  ] [p] = [0]
//! ```
//!
//! whose first row, with `p = (1−α) W C u`, is `K₀ u = r` exactly, for any `α` per term and
//! any operator in place of `K₀` (the solver's tangent `J`: the first block is then
//! `J − Cᵀ (1−α)W C`, with `C` and `W` taken on the current configuration). A second
//! multilevel preconditioner is built for the block `E + Cᵀ αW C`, which keeps the share
//! [`BLOCK_SHARE`] of the volumetric stiffness of every term stiffer than
//! `MultilevelParams::split_above` times its shear; the rest is the multiplier `p` (an
//! augmented Lagrangian: Fortin & Glowinski 1983; Benzi & Olshanskii, *SIAM J. Sci.
//! Comput.* 28, 2006). The preconditioner is block upper
//! triangular, `p = −r_p / s`, `u = B (r_u − Π Cᵀ p)`, with the Schur complement
//! `I + (1−α)W C B Cᵀ` approximated per term by `s = 1 + β (1−α)/α` ([`SCHUR_SCALE`]). The
//! second row is scaled by `(1−α)W` so that the mixed residual bounds the reduced one:
//! `K₀ u − r = ρ_u + Cᵀ ρ_p`.
//!
//! Measured on the jittered 8³ T4ANP block of this module's tests (GMRES to 1e-8 of the
//! reduced residual): ν = 0.499 133 → 89, ν = 0.4999 496 → 414 iterations (56 and 298 with
//! the Schur scalar unscaled, which the nonlinear solves like less: [`SCHUR_SCALE`]); on
//! the MNI152 brain at ν = 0.499, 1013 → 162–204 GMRES iterations in a whole solve. The
//! block leaves the pressures' geometric stiffness (`κ (J − 1)` times the second derivatives
//! of `J`) out; where the configuration is far from isochoric it exceeds the block's and the
//! mixed form stalls ([`VolumetricSplit::pays`]).

use bs_mesh::Vector3;
use rayon::prelude::*;

use super::projector::Projector;
use crate::linalg::krylov::NodalMap;
use crate::linalg::nodal::NodalMatrix;
use crate::linalg::sparse::RankOneSum;

/// The share `α` of a split term's volumetric stiffness kept in the preconditioned block (the rest
/// goes to the multiplier). Measured with `brainshift run` on the MNI152 brain (8 mm): at
/// ν = 0.499 `α` = 0.1 (a block `κ/μ` of 50) took 25 Newton / 290 GMRES iterations and 0.4
/// (200) 17 / 288, against 30 / 1013 without the split; at ν = 0.4999, 0.1 (500)
/// converged in 224 / 5815 (273 iterations without), 0.04 and 0.01 did not in 300. On the
/// tests' blocks (linear, ν = 0.4999) a block `κ/μ` of 10, 20, 50 took 128–169, 91–114,
/// 72–85 iterations. (Measured with the Schur scalar unscaled, before [`SCHUR_SCALE`].)
pub const BLOCK_SHARE: f64 = 0.1;

/// The split, kept by the preconditioner when a nodal term is stiffer than
/// `MultilevelParams::split_above` times its shear.
#[derive(Debug, Clone)]
pub struct VolumetricSplit {
    /// `C` and `W` of the reference configuration.
    c: RankOneSum,
    /// `α` per term.
    alpha: Vec<f64>,
    /// `1 / s` per term: the inverse of the approximate Schur complement.
    inv_schur: Vec<f64>,
    /// The `κ̄/μ̄` above which a term was split.
    above: f64,
}

/// The Schur complement `I + (1−α)W C B Cᵀ` is at most `1 + (1−α)/α` per term (the block's
/// shear stiffness takes part of the volumetric response); the preconditioner uses
/// `1 + SCHUR_SCALE (1−α)/α`. Measured with `brainshift run` at ν = 0.499 (Newton / GMRES
/// iterations, the MNI152 brain with E as is and perturbed three ways in the 10th–13th
/// digit): 1.0 22–25 / 240–288; 0.5 18–22 / 196–238; 0.4 17–19 / 175–195; 0.3 14–17 /
/// 161–173; 0.25 16 in all four / 162–204; 0.2 22–23; 0.1 20–22. With the brain, tumour
/// and ventricles of `fixtures/mni152-regions` as T4ANP at ν = 0.499: 1.0 24 / 299, 0.3
/// 26 / 309, 0.25 16 / 176 (without the split 29 / 526). At ν = 0.4999 (MNI152): 1.0 225 /
/// 5834, 0.3 164 / 5172, 0.25 178 / 6058. A linear solve to 1e-8 prefers 1.0 (the 8³
/// block at ν = 0.499: 56 iterations against 89): the Newton solves end early (forcing
/// 0.01–0.5), where a smaller `s` puts more of each correction into the multiplier and the
/// truncated direction is closer to isochoric.
pub const SCHUR_SCALE: f64 = 0.25;

/// Caller-owned buffers of [`VolumetricSplit::apply`] and
/// [`VolumetricSplit::precondition`].
#[derive(Debug, Default)]
pub struct SplitScratch {
    s: Vec<f64>,
    v: Vec<Vector3<f64>>,
}

/// Splits `k` when one of its nodal terms is stiffer than `above` times its shear (`None`
/// otherwise): the block `E + Cᵀ αW C` and the split.
pub(super) fn split(k: &NodalMatrix, above: f64) -> Option<(NodalMatrix, VolumetricSplit)> {
    let mut k = k.clone();
    let nodal = k.nodal.as_mut()?;
    if !k.ratio.iter().any(|&r| r > above) {
        return None;
    }
    let c = nodal.clone();
    let mut inv_schur = vec![1.0; nodal.terms()];
    let mut alphas = vec![1.0; nodal.terms()];
    for (t, &ratio) in k.ratio.iter().enumerate() {
        let alpha = if ratio > above { BLOCK_SHARE } else { 1.0 };
        nodal.weight[t] *= alpha;
        inv_schur[t] = 1.0 / (1.0 + SCHUR_SCALE * (1.0 - alpha) / alpha);
        alphas[t] = alpha;
    }
    Some((k, VolumetricSplit { c, alpha: alphas, inv_schur, above }))
}

impl VolumetricSplit {
    /// Length in nodal vectors of a mixed vector on `n` nodes: the multipliers packed three
    /// to a vector after the displacements.
    pub fn len(&self, n: usize) -> usize {
        n + self.c.terms().div_ceil(3)
    }

    /// The split on the configuration whose nodal volumetric term is `nodal` (the pattern of
    /// [`term`](Self::term)): its weights are scaled to the multiplier's share `1 − α`.
    pub fn moved<'a>(&'a self, nodal: &'a mut RankOneSum) -> Moved<'a> {
        nodal.weight.iter_mut().zip(&self.alpha).for_each(|(w, a)| *w *= 1.0 - a);
        Moved { c: nodal, split: self }
    }

    /// A copy of the nodal volumetric term `K₀` was built with (pattern and reference
    /// values), for [`moved`](Self::moved).
    pub fn term(&self) -> RankOneSum {
        self.c.clone()
    }

    /// The `κ/μ` above which a material's terms are split (those whose volume changes
    /// [`pays`](Self::pays) reads).
    pub fn above(&self) -> f64 {
        self.above
    }

    /// Whether the mixed form pays on a configuration whose tetrahedra change their volume
    /// by `dj` (99th percentile of `|J − 1|`): the pressures' geometric stiffness, about
    /// `κ dj`, must stay below the block's volumetric stiffness `α κ`
    /// ([`DISTORTION`]`= 0.6 α`).
    pub fn pays(&self, dj: f64) -> bool {
        dj <= DISTORTION
    }
}

/// See [`VolumetricSplit::pays`]. Measured on the MNI152 brain at ν = 0.499, `α` = 0.1: the
/// mixed GMRES met its forcing (0.5) in 7–25 iterations up to a 99th percentile of `|J − 1|`
/// of 0.066 and stalled at 0.54–0.89 after 200 iterations from 0.080 on; the other solves
/// use the preconditioner of the whole `K₀`.
pub const DISTORTION: f64 = 0.6 * BLOCK_SHARE;

/// A split with the multiplier's term on another configuration.
#[derive(Debug)]
pub struct Moved<'a> {
    c: &'a RankOneSum,
    split: &'a VolumetricSplit,
}

impl Moved<'_> {
    /// `out = A v` for the mixed operator, `ju` computing `Π J u` (the operator of the
    /// displacements).
    pub fn apply(
        &self,
        pi: &Projector,
        n: usize,
        v: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
        scratch: &mut SplitScratch,
        ju: &mut NodalMap<'_>,
    ) {
        let (vu, vp) = v.split_at(n);
        let (ou, op) = out.split_at_mut(n);
        ju(vu, ou);
        let c = self.c;
        let diff = &mut scratch.s;
        diff.resize(c.terms(), 0.0);
        // p − (1−α)W C u, then Π Cᵀ (p − (1−α)W C u) onto the first row.
        diff.par_iter_mut().enumerate().with_min_len(ROWS).for_each(|(t, d)| {
            *d = multiplier(vp, t) - c.project_row(t, vu);
        });
        let diff = &*diff;
        ou.par_iter_mut().enumerate().with_min_len(ROWS).for_each(|(a, o)| {
            *o += projected(pi, a, c.expand_row(a, diff));
        });
        pack(diff, -1.0, op);
    }

    /// `z = M⁻¹ r`: `p = −r_p / s`, `z_u = B (r_u − Π Cᵀ p)` with `b` applying the multilevel
    /// cycle.
    pub fn precondition(
        &self,
        pi: &Projector,
        n: usize,
        r: &[Vector3<f64>],
        z: &mut [Vector3<f64>],
        scratch: &mut SplitScratch,
        b: &mut NodalMap<'_>,
    ) {
        let c = self.c;
        let SplitScratch { s, v: ru } = scratch;
        s.resize(c.terms(), 0.0);
        let inv_schur = &self.split.inv_schur;
        s.par_iter_mut().enumerate().with_min_len(ROWS).for_each(|(t, st)| {
            *st = -multiplier(&r[n..], t) * inv_schur[t];
        });
        let s = &*s;
        ru.resize(n, Vector3::zeros());
        ru.par_iter_mut()
            .zip(r[..n].par_iter())
            .enumerate()
            .with_min_len(ROWS)
            .for_each(|(a, (x, ri))| *x = ri - projected(pi, a, c.expand_row(a, s)));
        let (zu, zp) = z.split_at_mut(n);
        b(ru, zu);
        pack(s, 1.0, zp);
    }
}

/// Rows (terms or nodes) per rayon task of the split's passes.
const ROWS: usize = 512;

/// `Π_a x`.
#[inline]
fn projected(pi: &Projector, a: usize, x: Vector3<f64>) -> Vector3<f64> {
    if pi.constrained[a] { pi.matrix[a] * x } else { x }
}

/// Multiplier `t` of the multipliers packed three to a nodal vector.
#[inline]
fn multiplier(packed: &[Vector3<f64>], t: usize) -> f64 {
    packed[t / 3][t % 3]
}

/// `sign · values` packed three to a nodal vector into `packed` (the last vector's unused
/// components zero).
fn pack(values: &[f64], sign: f64, packed: &mut [Vector3<f64>]) {
    packed.par_iter_mut().enumerate().with_min_len(ROWS).for_each(|(i, o)| {
        *o = Vector3::from_fn(|k, _| values.get(3 * i + k).map_or(0.0, |v| sign * v));
    });
}
