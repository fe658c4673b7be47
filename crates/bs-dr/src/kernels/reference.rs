//! The straightforward scalar TLED kernels, one element at a time: the reference the
//! vectorised kernels are tested against, the benchmark's baseline (the production path
//! before the SIMD kernels, kept callable as `Model::internal_forces_scalar_into`), and
//! the per-element path of blocks whose law has no lane-wise form.

use bs_material::Material;
use bs_mesh::Vector3;
use nalgebra::Matrix3;

use crate::element::kinematics::{deformation_gradient, det3};
use crate::element::{Hex, Tet};

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
