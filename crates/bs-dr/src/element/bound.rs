//! Per-element stiffness bounds: the largest eigenvalue `λ_max(K_e)` of each element's
//! small-strain stiffness (with the hourglass stiffness for hexahedra), from which the
//! critical time steps and Dynamic Relaxation's fictitious masses follow.

use bs_material::{Elastic, Tangent};
use nalgebra::{SMatrix, SymmetricEigen};

use super::Solid;
use super::hex::Hex;
use super::tet::Tet;

/// `D^(1/2)` of one material's small-strain moduli: what every element's bound shares.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BoundModuli {
    sqrt_d: Tangent,
}

impl BoundModuli {
    /// The moduli of each solid, in solid order.
    pub(crate) fn of(solids: &[Solid]) -> Vec<BoundModuli> {
        solids.iter().map(|s| BoundModuli::new(&s.material.elastic())).collect()
    }

    pub(crate) fn new(el: &Elastic) -> Self {
        let eig = SymmetricEigen::new(el.small_strain_tangent());
        let sqrt_d = eig.eigenvectors
            * Tangent::from_diagonal(&eig.eigenvalues.map(|v| v.max(0.0).sqrt()))
            * eig.eigenvectors.transpose();
        BoundModuli { sqrt_d }
    }
}

impl Tet {
    /// `λ_max` of the small-strain stiffness `V BᵀDB` for the moduli `m`.
    pub(crate) fn stiffness_bound(&self, m: &BoundModuli) -> f64 {
        consistent_stiffness_bound(&self.g, self.vol, m)
    }
}

impl Hex {
    /// `λ_max(V BᵀDB) + λ_max(K_hg)` for the moduli `m`: an upper bound of the largest
    /// eigenvalue of their sum.
    pub(crate) fn stiffness_bound(&self, m: &BoundModuli) -> f64 {
        let hg = SMatrix::<f64, 8, 8>::from_fn(|i, j| self.hg[i][j]);
        let hg_max = SymmetricEigen::new(hg).eigenvalues.max();
        consistent_stiffness_bound(&self.g, self.vol, m) + hg_max.max(0.0)
    }
}

/// Largest eigenvalue of the small-strain element stiffness `V BᵀDB` (3n×3n): its nonzero
/// eigenvalues equal those of the 6×6 matrix `V D^(1/2) (B Bᵀ) D^(1/2)`.
fn consistent_stiffness_bound(g: &[[f64; 3]], vol: f64, moduli: &BoundModuli) -> f64 {
    let mut bbt = Tangent::zeros();
    for ga in g {
        let b = strain_rows(ga);
        bbt += b * b.transpose();
    }
    let sqrt_d = &moduli.sqrt_d;
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
