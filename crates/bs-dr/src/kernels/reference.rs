//! The straightforward scalar TLED kernels, one element at a time: the reference the
//! vectorised kernels are tested against, the benchmark's baseline (the production path
//! before the SIMD kernels, kept callable as [`Model::internal_forces_scalar_into`]), and
//! the per-element path of blocks whose law has no lane-wise form.

use std::sync::atomic::{AtomicBool, Ordering};

use bs_material::Material;
use bs_mesh::Vector3;
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::forces::{Inversion, MIN_LEN};
use crate::model::{Hex, Model, Tet, TetFormulation};

/// `F = I + Σ_a u_a ⊗ g_a` (row i = displacement component, column j = reference direction).
#[inline(always)]
pub(crate) fn deformation_gradient<const N: usize>(
    u: &[Vector3<f64>],
    nodes: &[u32; N],
    g: &[[f64; 3]; N],
) -> Matrix3<f64> {
    let mut f = Matrix3::identity();
    for a in 0..N {
        let ua = &u[nodes[a] as usize];
        for j in 0..3 {
            for i in 0..3 {
                f[(i, j)] += ua[i] * g[a][j];
            }
        }
    }
    f
}

/// `det F` by the first-row expansion.
#[inline(always)]
pub(crate) fn det3(f: &Matrix3<f64>) -> f64 {
    f[(0, 0)] * (f[(1, 1)] * f[(2, 2)] - f[(1, 2)] * f[(2, 1)])
        - f[(0, 1)] * (f[(1, 0)] * f[(2, 2)] - f[(1, 2)] * f[(2, 0)])
        + f[(0, 2)] * (f[(1, 0)] * f[(2, 1)] - f[(1, 1)] * f[(2, 0)])
}

/// `out_a = scale · P g_a` for every node (`P` the first Piola–Kirchhoff stress).
#[inline(always)]
pub(crate) fn nodal_forces<const N: usize>(
    p: &Matrix3<f64>,
    scale: f64,
    g: &[[f64; 3]; N],
    out: &mut [Vector3<f64>],
) {
    let p = p * scale;
    for a in 0..N {
        out[a] = p * Vector3::from(g[a]);
    }
}

/// T4 forces of one tet into `out` (4 vectors); returns `J`. An inverted tet (`J ≤ 0` or
/// non-finite) gets zero forces.
#[inline]
pub(crate) fn t4_element(
    material: &Material,
    u: &[Vector3<f64>],
    t: &Tet,
    out: &mut [Vector3<f64>],
) -> f64 {
    let f = deformation_gradient(u, &t.nodes, &t.g);
    let j = det3(&f);
    if !(j > 0.0 && j.is_finite()) {
        out.iter_mut().for_each(|o| *o = Vector3::zeros());
        return j;
    }
    let p = material.pk1_fj(&f, j);
    nodal_forces(&p, t.vol, &t.g, out);
    j
}

/// `J = det F` of one tet.
#[inline]
pub(crate) fn tet_jacobian(u: &[Vector3<f64>], t: &Tet) -> f64 {
    det3(&deformation_gradient(u, &t.nodes, &t.g))
}

/// `J̄` of a tet: the mean of its four nodal volume ratios.
#[inline(always)]
pub(crate) fn anp_jbar(jnodal: &[f64], nodes: &[u32; 4]) -> f64 {
    0.25 * (jnodal[nodes[0] as usize]
        + jnodal[nodes[1] as usize]
        + jnodal[nodes[2] as usize]
        + jnodal[nodes[3] as usize])
}

/// T4ANP forces of one tet with element ratio `j` and averaged ratio `jbar`: the stress from
/// `F̄ = r F`, `r = (J̄/J)^(1/3)`, and `f_a = V r⁻² P̄(rF, J̄) g_a` (= `∫ σ̄ ∇ₓN_a dv` over the
/// current element volume). Returns `false` (zero forces) if `J` or `J̄` is not > 0 and
/// finite.
#[inline]
pub(crate) fn t4anp_element(
    material: &Material,
    u: &[Vector3<f64>],
    t: &Tet,
    j: f64,
    jbar: f64,
    out: &mut [Vector3<f64>],
) -> bool {
    if !(j > 0.0 && j.is_finite() && jbar > 0.0 && jbar.is_finite()) {
        out.iter_mut().for_each(|o| *o = Vector3::zeros());
        return false;
    }
    let f = deformation_gradient(u, &t.nodes, &t.g);
    let r = bs_material::inv_cbrt(j / jbar); // (J̄/J)^(1/3)
    // P̄ = P(F̄ = r F, J̄); f_a = V r⁻¹ F S̄ g_a = V r⁻² P̄ g_a.
    let p = material.pk1_fj(&(f * r), jbar);
    nodal_forces(&p, t.vol / (r * r), &t.g, out);
    true
}

/// H8 mean-strain forces of one hex plus its hourglass forces `K_hg u` into `out`
/// (8 vectors); returns `J`. An inverted hex gets zero forces.
#[inline]
pub(crate) fn h8_element(
    material: &Material,
    u: &[Vector3<f64>],
    h: &Hex,
    out: &mut [Vector3<f64>],
) -> f64 {
    let f = deformation_gradient(u, &h.nodes, &h.g);
    let j = det3(&f);
    if !(j > 0.0 && j.is_finite()) {
        out.iter_mut().for_each(|o| *o = Vector3::zeros());
        return j;
    }
    let p = material.pk1_fj(&f, j);
    nodal_forces(&p, h.vol, &h.g, out);
    for a in 0..8 {
        let mut acc = Vector3::zeros();
        for b in 0..8 {
            acc += u[h.nodes[b] as usize] * h.hg[a][b];
        }
        out[a] += acc;
    }
    j
}

/// Scratch buffers of [`Model::internal_forces_scalar_into`].
#[doc(hidden)]
#[derive(Debug, Clone)]
pub struct ReferenceWorkspace {
    slots: Vec<Vector3<f64>>,
    /// Per-element `J` (tets, then hexes).
    jac: Vec<f64>,
    /// ANP nodal volume ratios.
    jnodal: Vec<f64>,
}

impl Model {
    /// Scratch buffers for [`Model::internal_forces_scalar_into`].
    #[doc(hidden)]
    pub fn reference_workspace(&self) -> ReferenceWorkspace {
        ReferenceWorkspace {
            slots: vec![Vector3::zeros(); self.slot_count()],
            jac: vec![0.0; self.tets.len() + self.hexes.len()],
            jnodal: vec![0.0; self.node_count()],
        }
    }

    /// The scalar reference kernels (one element at a time, three T4ANP passes), with the
    /// same contract as [`Model::internal_forces_into`]. For tests and the benchmark's
    /// baseline only.
    #[doc(hidden)]
    pub fn internal_forces_scalar_into(
        &self,
        u: &[Vector3<f64>],
        ws: &mut ReferenceWorkspace,
        forces: &mut [Vector3<f64>],
    ) -> Result<(), Inversion> {
        assert_eq!(u.len(), self.node_count(), "displacement length must equal the node count");
        assert_eq!(forces.len(), self.node_count(), "force length must equal the node count");
        let nt = self.tets.len();
        let bad = AtomicBool::new(false);
        let (tslots, hslots) = ws.slots.split_at_mut(4 * nt);
        let (tjac, hjac) = ws.jac.split_at_mut(nt);
        match self.options.tet {
            TetFormulation::T4 => {
                tslots
                    .par_chunks_mut(4)
                    .zip(tjac.par_iter_mut())
                    .zip(self.tets.par_iter())
                    .with_min_len(MIN_LEN)
                    .for_each(|((out, jac), t)| {
                        *jac = t4_element(&self.solids[t.mat as usize].material, u, t, out);
                        if !(*jac > 0.0 && jac.is_finite()) {
                            bad.store(true, Ordering::Relaxed);
                        }
                    });
            }
            TetFormulation::T4Anp => {
                tjac.par_iter_mut()
                    .zip(self.tets.par_iter())
                    .with_min_len(MIN_LEN)
                    .for_each(|(jac, t)| *jac = tet_jacobian(u, t));
                let tjac_ro: &[f64] = tjac;
                let tets = &self.tets;
                ws.jnodal.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(n, jn)| {
                    let mut acc = 0.0;
                    let lo = self.gather_ptr[n] as usize;
                    let hi = self.gather_ptr[n + 1] as usize;
                    for &s in &self.gather_slot[lo..hi] {
                        let s = s as usize;
                        if s < 4 * nt {
                            let e = s / 4;
                            acc += tets[e].vol * tjac_ro[e];
                        }
                    }
                    *jn = acc * self.anp_inv_vol[n];
                });
                let jnodal: &[f64] = &ws.jnodal;
                tslots
                    .par_chunks_mut(4)
                    .zip(tjac_ro.par_iter())
                    .zip(self.tets.par_iter())
                    .with_min_len(MIN_LEN)
                    .for_each(|((out, &j), t)| {
                        let jbar = anp_jbar(jnodal, &t.nodes);
                        let m = &self.solids[t.mat as usize].material;
                        if !t4anp_element(m, u, t, j, jbar, out) {
                            bad.store(true, Ordering::Relaxed);
                        }
                    });
            }
        }
        hslots
            .par_chunks_mut(8)
            .zip(hjac.par_iter_mut())
            .zip(self.hexes.par_iter())
            .with_min_len(MIN_LEN / 4)
            .for_each(|((out, jac), h)| {
                *jac = h8_element(&self.solids[h.mat as usize].material, u, h, out);
                if !(*jac > 0.0 && jac.is_finite()) {
                    bad.store(true, Ordering::Relaxed);
                }
            });
        let slots: &[Vector3<f64>] = &ws.slots;
        forces.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(n, fo)| {
            let lo = self.gather_ptr[n] as usize;
            let hi = self.gather_ptr[n + 1] as usize;
            let mut acc = Vector3::zeros();
            for &s in &self.gather_slot[lo..hi] {
                acc += slots[s as usize];
            }
            *fo = acc;
        });
        if bad.load(Ordering::Relaxed) {
            let (tjac, hjac) = ws.jac.split_at(nt);
            return Err(self.first_inversion(|t| tjac[t], hjac, &ws.jnodal));
        }
        Ok(())
    }
}
