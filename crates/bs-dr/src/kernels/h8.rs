//! The H8 mean-strain hexahedron with stiffness hourglass control on blocks of four hexes
//! (one hex per lane): `F = I + Σ_a u_a ⊗ B̄_a`, the Neo-Hookean stress on lanes, the nodal
//! forces `V P B̄_a` and the hourglass forces `K_hg u`, then the 24 force rows transposed
//! to hex-major slots. Blocks with another law take the scalar per-element path.

use bs_mesh::Vector3;

use super::layout::{BlockLaw, HexBlock, LANES, sym_index};
use super::neo_hookean::{NhLanes, inv_cbrt, pk1_coefficients};
use super::reference;
use super::simd::{BlockOp, Lanes};
use super::tet_block::kinematics_of;
use crate::element::{Hex, Solid};

/// Forces of one block of hexes, hex-major: the 96 values `[lane][3a + component]` as 24
/// rows of four (hex `h`'s slot `8h + a` at `3(8h + a)` of the flattened buffer).
pub(crate) type HexBlockForces = [[f64; LANES]; 24];

/// H8 forces and `J` of a run of consecutive hex blocks.
pub(crate) struct H8Forces<'a> {
    pub blocks: &'a [HexBlock],
    /// The hexes of these blocks (`hexes[4i + l]` is lane `l` of `blocks[i]`).
    pub hexes: &'a [Hex],
    pub solids: &'a [Solid],
    pub u: &'a [Vector3<f64>],
    /// Displacements as `[x, y, z, 0]`.
    pub upad: &'a [[f64; 4]],
    pub out: &'a mut [HexBlockForces],
    pub jac: &'a mut [[f64; LANES]],
}

impl H8Forces<'_> {
    /// Block `i` through the scalar kernel, lane by lane.
    fn per_element(&mut self, i: usize) -> bool {
        let (out, jac) = (&mut self.out[i], &mut self.jac[i]);
        *out = [[0.0; LANES]; 24];
        *jac = [1.0; LANES];
        let mut bad = false;
        for (lane, h) in self.hexes.iter().skip(LANES * i).take(LANES).enumerate() {
            let mut f = [Vector3::zeros(); 8];
            let j = reference::h8_element(&self.solids[h.mat as usize].material, self.u, h, &mut f);
            jac[lane] = j;
            bad |= !(j > 0.0 && j.is_finite());
            let values = out[6 * lane..6 * lane + 6].as_flattened_mut();
            for a in 0..8 {
                for c in 0..3 {
                    values[3 * a + c] = f[a][c];
                }
            }
        }
        bad
    }
}

impl BlockOp for H8Forces<'_> {
    /// Whether some hex is inverted.
    type Output = bool;

    #[inline(always)]
    fn run<L: Lanes>(mut self, l: L) -> bool {
        let mut bad = false;
        for i in 0..self.blocks.len() {
            let b = &self.blocks[i];
            let BlockLaw::NeoHookean(e) = b.law else {
                bad |= self.per_element(i);
                continue;
            };
            let mut u = [[l.splat(0.0); 3]; 8];
            for a in 0..8 {
                u[a] = l.gather_xyz(self.upad, b.nodes[a]);
            }
            let mut f = [[l.splat(0.0); 3]; 3];
            for a in 0..8 {
                for j in 0..3 {
                    let g = l.load(b.g[3 * a + j]);
                    for r in 0..3 {
                        f[r][j] = l.mul_add(u[a][r], g, f[r][j]);
                    }
                }
            }
            let one = l.splat(1.0);
            for r in 0..3 {
                f[r][r] = l.add(f[r][r], one);
            }
            let k = kinematics_of(l, f);
            let rho = inv_cbrt(l, l.mul(k.det, k.det));
            // Hourglass forces first: they do not wait for the stress.
            let mut rows = [l.splat(0.0); 24];
            for a in 0..8 {
                for c in 0..8 {
                    let h = l.load(b.hg[sym_index(a, c)]);
                    for r in 0..3 {
                        rows[3 * a + r] = l.mul_add(h, u[c][r], rows[3 * a + r]);
                    }
                }
            }
            let nh = NhLanes { mu: l.splat(e.mu), kappa: l.splat(e.kappa) };
            let (alpha, beta) = pk1_coefficients(l, nh, k.det, k.det, k.i1, rho, l.load(b.vol));
            let mut p = k.f;
            for r in 0..3 {
                for j in 0..3 {
                    p[r][j] = l.mul_add(alpha, k.f[r][j], l.mul(beta, k.cof[r][j]));
                }
            }
            for a in 0..8 {
                let g = [l.load(b.g[3 * a]), l.load(b.g[3 * a + 1]), l.load(b.g[3 * a + 2])];
                for r in 0..3 {
                    let v =
                        l.mul_add(p[r][2], g[2], l.mul_add(p[r][1], g[1], l.mul(p[r][0], g[0])));
                    rows[3 * a + r] = l.add(rows[3 * a + r], v);
                }
            }
            // Hex-major: transposing rows 4q..4q+3 gives, for hex l, its values 4q..4q+3.
            let out = &mut self.out[i];
            for q in 0..6 {
                let t =
                    l.transpose([rows[4 * q], rows[4 * q + 1], rows[4 * q + 2], rows[4 * q + 3]]);
                for lane in 0..LANES {
                    out[6 * lane + q] = l.store(t[lane]);
                }
            }
            self.jac[i] = l.store(k.det);
            let valid = l.positive_finite_mask(k.det);
            if valid != 0b1111 {
                bad = true;
                for lane in 0..LANES {
                    if valid & (1 << lane) == 0 {
                        out[6 * lane..6 * lane + 6].fill([0.0; LANES]);
                    }
                }
            }
        }
        bad
    }
}
