//! The trilinear hexahedron in the mean-strain (uniform strain) formulation of Flanagan &
//! Belytschko (1981): volume-averaged gradients `B̄_a = (1/V) ∫ ∂N_a/∂X dV` (2×2×2 Gauss,
//! exact for a trilinear hex) and the stiffness hourglass matrix of [`super::hourglass`].

use bs_material::Elastic;
use bs_mesh::{HEX_REFERENCE as HEX_XI, Point3};

use super::hourglass::hourglass_matrix;
use super::view::ElementView;

/// Precomputed data of one mean-strain hexahedron.
#[derive(Debug, Clone)]
pub(crate) struct Hex {
    /// Node indices (Abaqus/VTK order).
    pub nodes: [u32; 8],
    /// Index of its [`Solid`](super::Solid).
    pub mat: u32,
    /// Reference volume.
    pub vol: f64,
    /// Mean (volume-averaged) shape-function gradients B̄_a = (1/V) ∫ ∂N_a/∂X dV.
    pub g: [[f64; 3]; 8],
    /// Hourglass stiffness matrix (8×8, acts on each displacement component).
    pub hg: [[f64; 8]; 8],
}

impl Hex {
    /// The hexahedron with nodes `nodes` at `x`, solid `mat` of small-strain moduli `el` and
    /// hourglass coefficient `kappa_hg`; `Err(det)` with its smallest Gauss-point Jacobian
    /// determinant when it is inverted or degenerate.
    pub(crate) fn new(
        nodes: [u32; 8],
        mat: u32,
        x: &[Point3<f64>; 8],
        el: &Elastic,
        kappa_hg: f64,
    ) -> Result<Hex, f64> {
        let (vol, g, min_det) = hex_mean_gradients(x);
        if !(min_det > 0.0 && vol > 0.0) {
            return Err(min_det);
        }
        let hg = hourglass_matrix(x, &g, vol, el, kappa_hg);
        Ok(Hex { nodes, mat, vol, g, hg })
    }

    /// The element as every per-element loop sees it.
    pub(crate) fn view(&self) -> ElementView<'_> {
        ElementView {
            nodes: &self.nodes,
            g: &self.g,
            vol: self.vol,
            mat: self.mat as usize,
            hg: Some(&self.hg),
        }
    }
}

/// Gauss points of the 2×2×2 rule (exact for the mean gradients of a trilinear hex).
const G: f64 = 0.577_350_269_189_625_8;

/// Mean gradients, volume and smallest Gauss-point Jacobian of a trilinear hex.
fn hex_mean_gradients(x: &[Point3<f64>; 8]) -> (f64, [[f64; 3]; 8], f64) {
    let mut vol = 0.0;
    let mut min_det = f64::INFINITY;
    let mut acc = [[0.0; 3]; 8];
    for gp in 0..8 {
        let p = [HEX_XI[gp][0] * G, HEX_XI[gp][1] * G, HEX_XI[gp][2] * G];
        // dN/dξ
        let mut dn = [[0.0; 3]; 8];
        for a in 0..8 {
            let s = HEX_XI[a];
            let f = [(1.0 + s[0] * p[0]), (1.0 + s[1] * p[1]), (1.0 + s[2] * p[2])];
            dn[a] = [
                0.125 * s[0] * f[1] * f[2],
                0.125 * s[1] * f[0] * f[2],
                0.125 * s[2] * f[0] * f[1],
            ];
        }
        // J_ij = ∂x_i/∂ξ_j
        let mut jm = nalgebra::Matrix3::zeros();
        for a in 0..8 {
            for i in 0..3 {
                for j in 0..3 {
                    jm[(i, j)] += x[a][i] * dn[a][j];
                }
            }
        }
        let det = jm.determinant();
        min_det = min_det.min(det);
        vol += det;
        let jinv = jm.try_inverse().unwrap_or_else(nalgebra::Matrix3::zeros);
        // ∂N/∂X = J⁻ᵀ ∂N/∂ξ, weighted by det (weights are 1).
        for a in 0..8 {
            for k in 0..3 {
                let mut s = 0.0;
                for j in 0..3 {
                    s += jinv[(j, k)] * dn[a][j];
                }
                acc[a][k] += s * det;
            }
        }
    }
    for row in acc.iter_mut() {
        for v in row.iter_mut() {
            *v /= vol;
        }
    }
    (vol, acc, min_det)
}
