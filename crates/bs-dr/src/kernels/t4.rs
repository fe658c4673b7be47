//! The T4 (constant-strain tetrahedron) kernel on blocks of four tets.

use bs_mesh::Vector3;

use super::layout::{LANES, TetBlock};
use super::neo_hookean::{NhLanes, inv_cbrt, pk1_coefficients};
use super::reference;
use super::simd::{BlockOp, Lanes};
use super::tet_block::{
    BlockForces, GROUP, Kinematics, group_laws, kinematics, nh_lanes, put_lane, store_forces,
    zero_invalid_lanes,
};
use crate::element::{Solid, Tet};

/// T4 forces and `J` of a run of consecutive blocks.
pub(crate) struct T4Forces<'a> {
    /// The blocks.
    pub blocks: &'a [TetBlock],
    /// The tets of these blocks (`tets[4i + l]` is lane `l` of `blocks[i]`; the last block
    /// may have fewer).
    pub tets: &'a [Tet],
    pub solids: &'a [Solid],
    pub u: &'a [Vector3<f64>],
    /// `u` as `[x, y, z, 0]`.
    pub upad: &'a [[f64; 4]],
    pub out: &'a mut [BlockForces],
    pub jac: &'a mut [[f64; LANES]],
}

/// Forces of one Neo-Hookean block from its kinematics and `ρ = J^(−2/3)`; returns whether
/// a lane is inverted.
#[inline(always)]
fn finish<L: Lanes>(
    l: L,
    b: &TetBlock,
    nh: NhLanes<L::V>,
    k: &Kinematics<L::V>,
    rho: L::V,
    out: &mut BlockForces,
    jac: &mut [f64; LANES],
) -> bool {
    let (alpha, beta) = pk1_coefficients(l, nh, k.det, k.det, k.i1, rho, l.load(b.vol));
    store_forces(l, b, &k.f, &k.cof, alpha, beta, out);
    *jac = l.store(k.det);
    let valid = l.positive_finite_mask(k.det);
    if valid != 0b1111 {
        zero_invalid_lanes(valid, out);
    }
    valid != 0b1111
}

impl T4Forces<'_> {
    /// One block on its own (the last blocks of a run, per-element laws).
    #[inline(always)]
    fn single<L: Lanes>(&mut self, l: L, i: usize) -> bool {
        let b = &self.blocks[i];
        if let Some(nh) = nh_lanes(l, b) {
            let k = kinematics(l, self.upad, b);
            let rho = inv_cbrt(l, l.mul(k.det, k.det));
            return finish(l, b, nh, &k, rho, &mut self.out[i], &mut self.jac[i]);
        }
        let (out, jac) = (&mut self.out[i], &mut self.jac[i]);
        *out = [[0.0; LANES]; 12];
        *jac = [1.0; LANES];
        let mut bad = false;
        for (lane, t) in self.tets.iter().skip(LANES * i).take(LANES).enumerate() {
            let mut fl = [Vector3::zeros(); 4];
            let m = &self.solids[t.mat as usize].material;
            let j = reference::t4_element(m, self.u, t, &mut fl);
            jac[lane] = j;
            bad |= !(j > 0.0 && j.is_finite());
            put_lane(lane, &fl, out);
        }
        bad
    }
}

impl BlockOp for T4Forces<'_> {
    /// Whether some element is inverted.
    type Output = bool;

    #[inline(always)]
    fn run<L: Lanes>(mut self, l: L) -> bool {
        let mut bad = false;
        let n = self.blocks.len();
        let mut i = 0;
        while i < n {
            let group = &self.blocks[i..n.min(i + GROUP)];
            if let Some(nhs) = group_laws(l, group) {
                let mut ks = [kinematics(l, self.upad, &group[0]); GROUP];
                for g in 1..GROUP {
                    ks[g] = kinematics(l, self.upad, &group[g]);
                }
                let mut rho = [l.splat(0.0); GROUP];
                for g in 0..GROUP {
                    rho[g] = inv_cbrt(l, l.mul(ks[g].det, ks[g].det));
                }
                for g in 0..GROUP {
                    let (out, jac) = (&mut self.out[i + g], &mut self.jac[i + g]);
                    bad |= finish(l, &group[g], nhs[g], &ks[g], rho[g], out, jac);
                }
                i += GROUP;
            } else {
                bad |= self.single(l, i);
                i += 1;
            }
        }
        bad
    }
}
