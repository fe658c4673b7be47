//! The T4ANP (average nodal pressure) kernel on blocks of four tets, in three passes:
//!
//! 1. [`Jacobians`]: `J` of every tet, and `V J` for the nodal average;
//! 2. [`nodal_ratio`]: `J_n = Σ V_e J_e / Σ V_e` at every node (fixed order);
//! 3. [`AnpForces`]: `J̄` = mean of the four `J_n`, and the forces `V r⁻² P̄(rF, J̄) g_a`,
//!    `r = (J̄/J)^(1/3)`, as one fused evaluation for the Neo-Hookean law (see
//!    [`pk1_coefficients`]).
//!
//! Pass 1 stores 16 bytes per tet; pass 3 recomputes `F` from the cache-resident
//! displacements rather than storing and re-reading 72 bytes per tet.

use bs_mesh::Vector3;

use super::layout::{BlockLaw, LANES, TetBlock};
use super::neo_hookean::{NhLanes, cofactor, cross2, frobenius2, pk1_coefficients};
use super::reference;
use super::simd::{BlockOp, Lanes};
use super::tet_block::{
    BlockForces, deformation_gradient, put_lane, store_forces, zero_invalid_lanes,
};
use crate::model::{Solid, Tet};

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
            let f = deformation_gradient(l, self.upad, b);
            let j = l.mul_add(
                f[0][0],
                cross2(l, f[1][1], f[2][2], f[1][2], f[2][1]),
                l.mul_add(
                    f[0][1],
                    cross2(l, f[1][2], f[2][0], f[1][0], f[2][2]),
                    l.mul(f[0][2], cross2(l, f[1][0], f[2][1], f[1][1], f[2][0])),
                ),
            );
            *jac = l.store(j);
            *vj = l.store(l.mul(l.load(b.vol), j));
        }
    }
}

/// Pass 2 at one node: `Σ V_e J_e / Σ V_e` over the node's tets, in slot order (`slots` are
/// the node's force slots; tet slots `4t + a` come first). `vj[t / 4][t % 4] = V_t J_t`.
#[inline]
pub(crate) fn nodal_ratio(
    slots: &[u32],
    tet_slots: usize,
    vj: &[[f64; LANES]],
    inv_vol: f64,
) -> f64 {
    let mut acc = 0.0;
    for &s in slots {
        let s = s as usize;
        if s >= tet_slots {
            break;
        }
        let t = s / 4;
        acc += vj[t / LANES][t % LANES];
    }
    acc * inv_vol
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

impl BlockOp for AnpForces<'_> {
    /// Whether some element has `J` or `J̄` not > 0 and finite.
    type Output = bool;

    #[inline(always)]
    fn run<L: Lanes>(self, l: L) -> bool {
        let mut bad = false;
        let jn = self.jnodal;
        for (i, ((b, out), jac)) in
            self.blocks.iter().zip(self.out.iter_mut()).zip(self.jac).enumerate()
        {
            match b.law {
                BlockLaw::NeoHookean(e) => {
                    // J̄ = ¼ (((J₀ + J₁) + J₂) + J₃), in the scalar order.
                    let mut jsum = l.splat(0.0);
                    for (a, nodes) in b.nodes.iter().enumerate() {
                        let ja = l.load([
                            jn[nodes[0] as usize],
                            jn[nodes[1] as usize],
                            jn[nodes[2] as usize],
                            jn[nodes[3] as usize],
                        ]);
                        jsum = if a == 0 { ja } else { l.add(jsum, ja) };
                    }
                    let jbar = l.mul(l.splat(0.25), jsum);
                    let j = l.load(*jac);
                    let f = deformation_gradient(l, self.upad, b);
                    let cof = cofactor(l, &f);
                    let nh = NhLanes { mu: l.splat(e.mu), kappa: l.splat(e.kappa) };
                    let i1 = frobenius2(l, &f);
                    let (alpha, beta) = pk1_coefficients(l, nh, j, jbar, i1, l.load(b.vol));
                    store_forces(l, b, &f, &cof, alpha, beta, out);
                    let valid = l.positive_finite_mask(j) & l.positive_finite_mask(jbar);
                    if valid != 0b1111 {
                        bad = true;
                        zero_invalid_lanes(valid, out);
                    }
                }
                BlockLaw::PerElement => {
                    *out = [[0.0; LANES]; 12];
                    for (lane, t) in self.tets.iter().skip(LANES * i).take(LANES).enumerate() {
                        let mut fl = [Vector3::zeros(); 4];
                        let m = &self.solids[t.mat as usize].material;
                        let jbar = reference::anp_jbar(jn, &t.nodes);
                        bad |= !reference::t4anp_element(m, self.u, t, jac[lane], jbar, &mut fl);
                        put_lane(lane, &fl, out);
                    }
                }
            }
        }
        bad
    }
}
