//! What the T4 and T4ANP block kernels share: the deformation gradients of four tets from
//! the padded displacements, the nodal forces `V P g_a` written to the block's slots, and the
//! handling of inverted lanes.

use bs_mesh::Vector3;

use super::layout::{BlockLaw, LANES, TetBlock};
use super::neo_hookean::{Mat, NhLanes, cofactor, det_from_cofactor, frobenius2};
use super::simd::Lanes;

/// Forces of one block, tet-major: the 48 values `[lane][3a + component]` as 12 rows of
/// four, so that tet `t`'s slot `s = 4t + a` starts at `3s` in the flattened buffer, as in
/// the scalar `Vec<Vector3>` slot layout, and the gather reads each slot as one vector.
pub(crate) type BlockForces = [[f64; LANES]; 12];

/// `F = I + Σ_a u_a ⊗ g_a` for the four lanes of `b`; `upad` holds `[x, y, z, 0]` per node.
/// Since `g_0 = −(g_1 + g_2 + g_3)`, computed as `I + Σ_{a≥1} (u_a − u_0) ⊗ g_a` (27
/// multiply-adds and 9 subtractions instead of 36 multiply-adds).
#[inline(always)]
pub(crate) fn deformation_gradient<L: Lanes>(l: L, upad: &[[f64; 4]], b: &TetBlock) -> Mat<L::V> {
    let u0 = l.gather_xyz(upad, b.nodes[0]);
    let mut f = [[l.splat(0.0); 3]; 3];
    for a in 1..4 {
        let ua = l.gather_xyz(upad, b.nodes[a]);
        let d = [l.sub(ua[0], u0[0]), l.sub(ua[1], u0[1]), l.sub(ua[2], u0[2])];
        for j in 0..3 {
            let g = l.load(b.g[3 * (a - 1) + j]);
            for i in 0..3 {
                f[i][j] = if a == 1 { l.mul(d[i], g) } else { l.mul_add(d[i], g, f[i][j]) };
            }
        }
    }
    let one = l.splat(1.0);
    for i in 0..3 {
        f[i][i] = l.add(f[i][i], one);
    }
    f
}

/// `f_a = (α F + β cof F) g_a` for the four nodes, into `out`.
#[inline(always)]
pub(crate) fn store_forces<L: Lanes>(
    l: L,
    b: &TetBlock,
    f: &Mat<L::V>,
    cof: &Mat<L::V>,
    alpha: L::V,
    beta: L::V,
    out: &mut BlockForces,
) {
    let mut p = *f;
    for i in 0..3 {
        for j in 0..3 {
            p[i][j] = l.mul_add(alpha, f[i][j], l.mul(beta, cof[i][j]));
        }
    }
    // f_1, f_2, f_3 from their gradients, f_0 = −(f_1 + f_2 + f_3) (as g_0 = −Σ g_a);
    // rows[3a + i] holds component i of f_a, one tet per lane.
    let mut rows = [l.splat(0.0); 12];
    for a in 1..4 {
        let r = 3 * (a - 1);
        let g = [l.load(b.g[r]), l.load(b.g[r + 1]), l.load(b.g[r + 2])];
        for i in 0..3 {
            let v = l.mul_add(p[i][2], g[2], l.mul_add(p[i][1], g[1], l.mul(p[i][0], g[0])));
            rows[3 * a + i] = v;
            rows[i] = l.sub(rows[i], v);
        }
    }
    // Tet-major: transposing rows 4k..4k+3 gives, for tet l, its values 4k..4k+3.
    for k in 0..3 {
        let t = l.transpose([rows[4 * k], rows[4 * k + 1], rows[4 * k + 2], rows[4 * k + 3]]);
        for lane in 0..LANES {
            out[3 * lane + k] = l.store(t[lane]);
        }
    }
}

/// Zeroes the forces of the lanes whose bit in `valid` is clear.
#[inline(always)]
pub(crate) fn zero_invalid_lanes(valid: u8, out: &mut BlockForces) {
    for l in 0..LANES {
        if valid & (1 << l) == 0 {
            out[3 * l..3 * l + 3].fill([0.0; LANES]);
        }
    }
}

/// Copies the four nodal forces of one element into lane `l` of a block's slots.
#[inline(always)]
pub(crate) fn put_lane(lane: usize, f: &[Vector3<f64>; 4], out: &mut BlockForces) {
    let values = out[3 * lane..3 * lane + 3].as_flattened_mut();
    for a in 0..4 {
        for i in 0..3 {
            values[3 * a + i] = f[a][i];
        }
    }
}

/// Blocks evaluated together, phase by phase (kinematics of all, then the cube roots of all,
/// then the forces of all). One block alone is a chain of dependent operations (the cube
/// root's iterations above all) that leaves the FMA units idle; a few independent blocks in
/// each phase keep them busy.
pub(crate) const GROUP: usize = 4;

/// `F`, `cof F`, `det F` and `I₁ = F:F` of one block.
#[derive(Clone, Copy)]
pub(crate) struct Kinematics<V> {
    pub f: Mat<V>,
    pub cof: Mat<V>,
    pub det: V,
    pub i1: V,
}

/// [`Kinematics`] of block `b`.
#[inline(always)]
pub(crate) fn kinematics<L: Lanes>(l: L, upad: &[[f64; 4]], b: &TetBlock) -> Kinematics<L::V> {
    kinematics_of(l, deformation_gradient(l, upad, b))
}

/// [`Kinematics`] of a known `F`.
#[inline(always)]
pub(crate) fn kinematics_of<L: Lanes>(l: L, f: Mat<L::V>) -> Kinematics<L::V> {
    let cof = cofactor(l, &f);
    let det = det_from_cofactor(l, &f, &cof);
    Kinematics { f, cof, det, i1: frobenius2(l, &f) }
}

/// The Neo-Hookean parameters of a block as lanes (`None` for a per-element block).
#[inline(always)]
pub(crate) fn nh_lanes<L: Lanes>(l: L, b: &TetBlock) -> Option<NhLanes<L::V>> {
    match b.law {
        BlockLaw::NeoHookean(e) => Some(NhLanes { mu: l.splat(e.mu), kappa: l.splat(e.kappa) }),
        BlockLaw::PerElement => None,
    }
}

/// The Neo-Hookean parameters of a full group of Neo-Hookean blocks, else `None`.
#[inline(always)]
pub(crate) fn group_laws<L: Lanes>(l: L, group: &[TetBlock]) -> Option<[NhLanes<L::V>; GROUP]> {
    if group.len() != GROUP {
        return None;
    }
    let zero = l.splat(0.0);
    let mut nhs = [NhLanes { mu: zero, kappa: zero }; GROUP];
    for g in 0..GROUP {
        nhs[g] = nh_lanes(l, &group[g])?;
    }
    Some(nhs)
}
