//! The H8 mean-strain hexahedron with stiffness hourglass control, one hex at a time with
//! the three displacement components in the lanes of one vector (`[x, y, z, 0]`): `F`, the
//! nodal forces `V P g_a` and the hourglass forces `K_hg u` are vector multiply-adds; the
//! stress is the scalar `Material::pk1_fj` (any law).

use nalgebra::Matrix3;

use super::reference::det3;
use super::simd::{BlockOp, Lanes};
use crate::model::{Hex, Solid};

/// H8 forces (8 slots per hex) and `J` of a run of consecutive hexes.
pub(crate) struct H8Forces<'a> {
    pub hexes: &'a [Hex],
    pub solids: &'a [Solid],
    /// Displacements as `[x, y, z, 0]`.
    pub upad: &'a [[f64; 4]],
    /// 8 slots per hex.
    pub out: &'a mut [[f64; 3]],
    pub jac: &'a mut [f64],
}

impl BlockOp for H8Forces<'_> {
    /// Whether some hex is inverted.
    type Output = bool;

    #[inline(always)]
    fn run<L: Lanes>(self, l: L) -> bool {
        let mut bad = false;
        for ((h, out), jac) in
            self.hexes.iter().zip(self.out.chunks_exact_mut(8)).zip(self.jac.iter_mut())
        {
            let mut ua = [l.splat(0.0); 8];
            for (v, &n) in ua.iter_mut().zip(&h.nodes) {
                *v = l.load(self.upad[n as usize]);
            }
            // Columns of F: F e_j = e_j + Σ_a u_a g_a[j].
            let mut fc = [
                l.load([1.0, 0.0, 0.0, 0.0]),
                l.load([0.0, 1.0, 0.0, 0.0]),
                l.load([0.0, 0.0, 1.0, 0.0]),
            ];
            for a in 0..8 {
                for j in 0..3 {
                    fc[j] = l.mul_add(ua[a], l.splat(h.g[a][j]), fc[j]);
                }
            }
            let c = [l.store(fc[0]), l.store(fc[1]), l.store(fc[2])];
            let f = Matrix3::new(
                c[0][0], c[1][0], c[2][0], c[0][1], c[1][1], c[2][1], c[0][2], c[1][2], c[2][2],
            );
            let j = det3(&f);
            *jac = j;
            if !(j > 0.0 && j.is_finite()) {
                bad = true;
                out.fill([0.0; 3]);
                continue;
            }
            let p = self.solids[h.mat as usize].material.pk1_fj(&f, j) * h.vol;
            let pc = [
                l.load([p[(0, 0)], p[(1, 0)], p[(2, 0)], 0.0]),
                l.load([p[(0, 1)], p[(1, 1)], p[(2, 1)], 0.0]),
                l.load([p[(0, 2)], p[(1, 2)], p[(2, 2)], 0.0]),
            ];
            for a in 0..8 {
                let g = &h.g[a];
                let mut acc = l.mul(pc[0], l.splat(g[0]));
                acc = l.mul_add(pc[1], l.splat(g[1]), acc);
                acc = l.mul_add(pc[2], l.splat(g[2]), acc);
                for b in 0..8 {
                    acc = l.mul_add(l.splat(h.hg[a][b]), ua[b], acc);
                }
                let v = l.store(acc);
                out[a] = [v[0], v[1], v[2]];
            }
        }
        bad
    }
}
