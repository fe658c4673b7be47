//! What the T4 and T4ANP block kernels share: the deformation gradients of four tets from
//! the padded displacements, the nodal forces `V P g_a` written to the block's slots, and the
//! handling of inverted lanes.

use bs_mesh::Vector3;

use super::layout::{LANES, TetBlock};
use super::neo_hookean::Mat;
use super::simd::Lanes;

/// Forces of one block: `[3a + component][lane]`.
pub(crate) type BlockForces = [[f64; LANES]; 12];

/// `F = I + Σ_a u_a ⊗ g_a` for the four lanes of `b`; `upad` holds `[x, y, z, 0]` per node.
#[inline(always)]
pub(crate) fn deformation_gradient<L: Lanes>(l: L, upad: &[[f64; 4]], b: &TetBlock) -> Mat<L::V> {
    let (zero, one) = (l.splat(0.0), l.splat(1.0));
    let mut f = [[one, zero, zero], [zero, one, zero], [zero, zero, one]];
    for a in 0..4 {
        let ua = l.gather_xyz(upad, b.nodes[a]);
        for j in 0..3 {
            let g = l.load(b.g[3 * a + j]);
            for i in 0..3 {
                f[i][j] = l.mul_add(ua[i], g, f[i][j]);
            }
        }
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
    for a in 0..4 {
        let g = [l.load(b.g[3 * a]), l.load(b.g[3 * a + 1]), l.load(b.g[3 * a + 2])];
        for i in 0..3 {
            let v = l.mul_add(p[i][2], g[2], l.mul_add(p[i][1], g[1], l.mul(p[i][0], g[0])));
            out[3 * a + i] = l.store(v);
        }
    }
}

/// Zeroes the forces of the lanes whose bit in `valid` is clear.
#[inline(always)]
pub(crate) fn zero_invalid_lanes(valid: u8, out: &mut BlockForces) {
    for l in 0..LANES {
        if valid & (1 << l) == 0 {
            for row in out.iter_mut() {
                row[l] = 0.0;
            }
        }
    }
}

/// Copies the four nodal forces of one element into lane `l` of a block's slots.
#[inline(always)]
pub(crate) fn put_lane(lane: usize, f: &[Vector3<f64>; 4], out: &mut BlockForces) {
    for a in 0..4 {
        for i in 0..3 {
            out[3 * a + i][lane] = f[a][i];
        }
    }
}
