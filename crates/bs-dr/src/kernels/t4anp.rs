//! The T4ANP (average nodal pressure) kernel on blocks of four tets, in three passes:
//!
//! 1. [`Jacobians`]: `J` of every tet, and `V J` for the nodal average;
//! 2. [`nodal_ratio`]: `J_n = Σ V_e J_e / Σ V_e` at every node (fixed order);
//! 3. [`AnpForces`]: `J̄` = mean of the four `J_n`, and the forces `V r⁻² P̄(rF, J̄) g_a`,
//!    `r = (J̄/J)^(1/3)`, as one fused evaluation for the Neo-Hookean law (see
//!    [`pk1_coefficients`]).
//!
//! Pass 1 keeps `J` and `V J` (16 bytes per tet); pass 3 recomputes `F` from the
//! cache-resident displacements. Keeping `F` from pass 1 instead (72 bytes per tet written
//! and read again) was measured slower on the shared machine: the step is bound by memory
//! traffic as much as by arithmetic.

use bs_mesh::Vector3;

use super::layout::{LANES, TetBlock};
use super::neo_hookean::{NhLanes, det, inv_cbrt, pk1_coefficients};
use super::reference;
use super::simd::{BlockOp, Lanes};
use super::tet_block::{
    BlockForces, GROUP, Kinematics, deformation_gradient, group_laws, kinematics, nh_lanes,
    put_lane, store_forces, zero_invalid_lanes,
};
use crate::element::{Solid, Tet};

/// Pass 1: `J` and `V J` of a run of consecutive blocks.
pub(crate) struct Jacobians<'a> {
    pub blocks: &'a [TetBlock],
    pub upad: &'a [[f64; 4]],
    pub jac: &'a mut [[f64; LANES]],
    pub vj: &'a mut [[f64; LANES]],
}

impl BlockOp for Jacobians<'_> {
    type Output = ();

    #[inline(always)]
    fn run<L: Lanes>(self, l: L) {
        for ((b, jac), vj) in self.blocks.iter().zip(self.jac.iter_mut()).zip(self.vj.iter_mut()) {
            let j = det(l, &deformation_gradient(l, self.upad, b));
            *jac = l.store(j);
            *vj = l.store(l.mul(l.load(b.vol), j));
        }
    }
}

/// Pass 2 at one node: `Σ V_e J_e / Σ V_e` over the node's tets, in a fixed order (`slots`
/// are the node's tet slots `4t + a`, increasing). `vj[t / 4][t % 4] = V_t J_t`.
#[inline]
pub(crate) fn nodal_ratio(slots: &[u32], vj: &[[f64; LANES]], inv_vol: f64) -> f64 {
    // Two partial sums (even and odd positions) for two independent add chains.
    // Blocked `[t / 4][t % 4]` is tet `t` in the flattened buffer.
    let vj = vj.as_flattened();
    let vj_of = |s: u32| vj[s as usize / 4];
    let mut pairs = slots.chunks_exact(2);
    let (mut even, mut odd) = (0.0, 0.0);
    for p in &mut pairs {
        even += vj_of(p[0]);
        odd += vj_of(p[1]);
    }
    if let [s] = pairs.remainder() {
        even += vj_of(*s);
    }
    (even + odd) * inv_vol
}

/// Pass 3: T4ANP forces of a run of consecutive blocks.
pub(crate) struct AnpForces<'a> {
    pub blocks: &'a [TetBlock],
    /// The tets of these blocks (`tets[4i + l]` is lane `l` of `blocks[i]`).
    pub tets: &'a [Tet],
    pub solids: &'a [Solid],
    pub u: &'a [Vector3<f64>],
    pub upad: &'a [[f64; 4]],
    /// `J` from pass 1.
    pub jac: &'a [[f64; LANES]],
    /// `J_n` from pass 2 (per node).
    pub jnodal: &'a [f64],
    pub out: &'a mut [BlockForces],
}

/// `J̄ = ¼ (((J_g0 + J_g1) + J_g2) + J_g3)` of a block's lanes (`g` the corners' averaging
/// groups), in the scalar order.
#[inline(always)]
fn jbar_lanes<L: Lanes>(l: L, b: &TetBlock, jn: &[f64]) -> L::V {
    let mut jsum = l.splat(0.0);
    for (a, groups) in b.anp.iter().enumerate() {
        let ja = l.load([
            jn[groups[0] as usize],
            jn[groups[1] as usize],
            jn[groups[2] as usize],
            jn[groups[3] as usize],
        ]);
        jsum = if a == 0 { ja } else { l.add(jsum, ja) };
    }
    l.mul(l.splat(0.25), jsum)
}

/// Forces of one Neo-Hookean block from `J`, `J̄`, its kinematics and `ρ = J^(−2/3)`;
/// returns whether a lane has `J` or `J̄` not > 0 and finite.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn finish<L: Lanes>(
    l: L,
    b: &TetBlock,
    nh: NhLanes<L::V>,
    j: L::V,
    jbar: L::V,
    k: &Kinematics<L::V>,
    rho: L::V,
    out: &mut BlockForces,
) -> bool {
    let (alpha, beta) = pk1_coefficients(l, nh, j, jbar, k.i1, rho, l.load(b.vol));
    store_forces(l, b, &k.f, &k.cof, alpha, beta, out);
    let valid = l.positive_finite_mask(j) & l.positive_finite_mask(jbar);
    if valid != 0b1111 {
        zero_invalid_lanes(valid, out);
    }
    valid != 0b1111
}

impl AnpForces<'_> {
    /// One block on its own (the last blocks of a run, per-element laws).
    #[inline(always)]
    fn single<L: Lanes>(&mut self, l: L, i: usize) -> bool {
        let (b, jac, jn) = (&self.blocks[i], &self.jac[i], self.jnodal);
        if let Some(nh) = nh_lanes(l, b) {
            let (j, jbar) = (l.load(*jac), jbar_lanes(l, b, jn));
            let rho = inv_cbrt(l, l.mul(j, j));
            let k = kinematics(l, self.upad, b);
            return finish(l, b, nh, j, jbar, &k, rho, &mut self.out[i]);
        }
        let out = &mut self.out[i];
        *out = [[0.0; LANES]; 12];
        let mut bad = false;
        for (lane, t) in self.tets.iter().skip(LANES * i).take(LANES).enumerate() {
            let mut fl = [Vector3::zeros(); 4];
            let m = &self.solids[t.mat as usize].material;
            let jbar = reference::anp_jbar(jn, &t.anp);
            bad |= !reference::t4anp_element(m, self.u, t, jac[lane], jbar, &mut fl);
            put_lane(lane, &fl, out);
        }
        bad
    }
}

impl BlockOp for AnpForces<'_> {
    /// Whether some element has `J` or `J̄` not > 0 and finite.
    type Output = bool;

    #[inline(always)]
    fn run<L: Lanes>(mut self, l: L) -> bool {
        let mut bad = false;
        let n = self.blocks.len();
        let mut i = 0;
        while i < n {
            let group = &self.blocks[i..n.min(i + GROUP)];
            if let Some(nhs) = group_laws(l, group) {
                let zero = l.splat(0.0);
                let (mut j, mut jbar, mut rho) = ([zero; GROUP], [zero; GROUP], [zero; GROUP]);
                for g in 0..GROUP {
                    j[g] = l.load(self.jac[i + g]);
                    jbar[g] = jbar_lanes(l, &group[g], self.jnodal);
                }
                for g in 0..GROUP {
                    rho[g] = inv_cbrt(l, l.mul(j[g], j[g]));
                }
                let mut ks = [kinematics(l, self.upad, &group[0]); GROUP];
                for g in 1..GROUP {
                    ks[g] = kinematics(l, self.upad, &group[g]);
                }
                for g in 0..GROUP {
                    let out = &mut self.out[i + g];
                    bad |= finish(l, &group[g], nhs[g], j[g], jbar[g], &ks[g], rho[g], out);
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
