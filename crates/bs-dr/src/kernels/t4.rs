//! The T4 (constant-strain tetrahedron) kernel on blocks of four tets.

use bs_mesh::Vector3;

use super::layout::{BlockLaw, LANES, TetBlock};
use super::neo_hookean::{NhLanes, cofactor, det_from_cofactor, frobenius2, pk1_coefficients};
use super::reference;
use super::simd::{BlockOp, Lanes};
use super::tet_block::{
    BlockForces, deformation_gradient, put_lane, store_forces, zero_invalid_lanes,
};
use crate::model::{Solid, Tet};

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

impl BlockOp for T4Forces<'_> {
    /// Whether some element is inverted.
    type Output = bool;

    #[inline(always)]
    fn run<L: Lanes>(self, l: L) -> bool {
        let mut bad = false;
        for (i, ((b, out), jac)) in
            self.blocks.iter().zip(self.out.iter_mut()).zip(self.jac.iter_mut()).enumerate()
        {
            match b.law {
                BlockLaw::NeoHookean(e) => {
                    let f = deformation_gradient(l, self.upad, b);
                    let cof = cofactor(l, &f);
                    let j = det_from_cofactor(l, &f, &cof);
                    let nh = NhLanes { mu: l.splat(e.mu), kappa: l.splat(e.kappa) };
                    let i1 = frobenius2(l, &f);
                    let (alpha, beta) = pk1_coefficients(l, nh, j, j, i1, l.load(b.vol));
                    store_forces(l, b, &f, &cof, alpha, beta, out);
                    *jac = l.store(j);
                    let valid = l.positive_finite_mask(j);
                    if valid != 0b1111 {
                        bad = true;
                        zero_invalid_lanes(valid, out);
                    }
                }
                BlockLaw::PerElement => {
                    *out = [[0.0; LANES]; 12];
                    *jac = [1.0; LANES];
                    for (lane, t) in self.tets.iter().skip(LANES * i).take(LANES).enumerate() {
                        let mut fl = [Vector3::zeros(); 4];
                        let m = &self.solids[t.mat as usize].material;
                        let j = reference::t4_element(m, self.u, t, &mut fl);
                        jac[lane] = j;
                        bad |= !(j > 0.0 && j.is_finite());
                        put_lane(lane, &fl, out);
                    }
                }
            }
        }
        bad
    }
}
