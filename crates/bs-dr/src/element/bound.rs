//! Per-element stiffness bounds: the largest eigenvalue `λ_max(K_e)` of each element's
//! small-strain stiffness (with the hourglass stiffness for hexahedra), from which the
//! critical time steps and Dynamic Relaxation's fictitious masses follow.

use bs_material::{Elastic, Tangent};
use nalgebra::{SMatrix, SymmetricEigen};

use super::hex::Hex;
use super::tet::Tet;

impl Tet {
    /// `λ_max` of the small-strain stiffness `V BᵀDB` for moduli `el`.
    pub(crate) fn stiffness_bound(&self, el: &Elastic) -> f64 {
        consistent_stiffness_bound(&self.g, self.vol, el)
    }
}

impl Hex {
    /// `λ_max(V BᵀDB) + λ_max(K_hg)` for moduli `el`: an upper bound of the largest
    /// eigenvalue of their sum.
    pub(crate) fn stiffness_bound(&self, el: &Elastic) -> f64 {
        let hg = SMatrix::<f64, 8, 8>::from_fn(|i, j| self.hg[i][j]);
        let hg_max = SymmetricEigen::new(hg).eigenvalues.max();
        consistent_stiffness_bound(&self.g, self.vol, el) + hg_max.max(0.0)
    }
}

/// Largest eigenvalue of the small-strain element stiffness `V BᵀDB` (3n×3n): its nonzero
/// eigenvalues equal those of the 6×6 matrix `V D^(1/2) (B Bᵀ) D^(1/2)`.
fn consistent_stiffness_bound(g: &[[f64; 3]], vol: f64, el: &Elastic) -> f64 {
    let mut bbt = Tangent::zeros();
    for ga in g {
        let b = strain_rows(ga);
        bbt += b * b.transpose();
    }
    let d = el.small_strain_tangent();
    let eig = SymmetricEigen::new(d);
    let sqrt_d = eig.eigenvectors
        * Tangent::from_diagonal(&eig.eigenvalues.map(|v| v.max(0.0).sqrt()))
        * eig.eigenvectors.transpose();
    let m = sqrt_d * bbt * sqrt_d;
    let m = (m + m.transpose()) * 0.5;
    vol * SymmetricEigen::new(m).eigenvalues.max()
}

/// Small-strain B block (6×3) of a node with gradient `g`, Voigt (11,22,33,23,13,12) with
/// engineering shear.
fn strain_rows(g: &[f64; 3]) -> SMatrix<f64, 6, 3> {
    SMatrix::<f64, 6, 3>::from_row_slice(&[
        g[0], 0.0, 0.0, //
        0.0, g[1], 0.0, //
        0.0, 0.0, g[2], //
        0.0, g[2], g[1], //
        g[2], 0.0, g[0], //
        g[1], g[0], 0.0,
    ])
}
