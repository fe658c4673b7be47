//! The stiffness hourglass control of the mean-strain hexahedron: the four hourglass base
//! vectors made orthogonal to the linear fields, and the 8×8 matrix that resists them on each
//! displacement component.

use bs_material::Elastic;
use bs_mesh::{HEX_REFERENCE as HEX_XI, Point3};

/// Flanagan–Belytschko stiffness hourglass matrix in the Total Lagrangian form of Joldes,
/// Wittek & Miller (2008): with the hourglass base vectors Γ_α (α = 1..4, entries ±1:
/// ξη, ηζ, ζξ, ξηζ at the nodes), the orthogonalised vectors
/// `γ_α = Γ_α − Σ_i (Γ_α · X_i) B̄_i` (X_i, B̄_i: nodal vectors of coordinate i and mean
/// gradient component i) annihilate every linear displacement field; the matrix is
/// `K_hg = k Σ_α γ_α γ_αᵀ` with `k = κ_hg · 2μ · V (B̄:B̄) / 3`.
///
/// Flanagan & Belytschko scale with the P-wave modulus `λ + 2μ`; for nearly incompressible
/// tissue (ν = 0.49–0.499) that makes the hourglass modes as stiff as the bulk and locks the
/// element (measured: 9× the T4ANP indentation force at ν = 0.499). Hourglass modes are
/// isochoric to first order, so the shear modulus is the physical scale: we use `2μ`, which
/// equals FB's `λ + 2μ` at ν = 0 and is softer above.
pub(crate) fn hourglass_matrix(
    x: &[Point3<f64>; 8],
    g: &[[f64; 3]; 8],
    vol: f64,
    el: &Elastic,
    kappa_hg: f64,
) -> [[f64; 8]; 8] {
    let mut gammas = [[0.0; 8]; 4];
    for (alpha, gamma) in gammas.iter_mut().enumerate() {
        let mut base = [0.0; 8];
        for a in 0..8 {
            let s = HEX_XI[a];
            base[a] = match alpha {
                0 => s[0] * s[1],
                1 => s[1] * s[2],
                2 => s[2] * s[0],
                _ => s[0] * s[1] * s[2],
            };
        }
        let mut proj = [0.0; 3];
        for (i, pi) in proj.iter_mut().enumerate() {
            *pi = (0..8).map(|a| base[a] * x[a][i]).sum();
        }
        for a in 0..8 {
            gamma[a] = base[a] - (0..3).map(|i| proj[i] * g[a][i]).sum::<f64>();
        }
    }
    let bb: f64 = g.iter().map(|r| r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sum();
    let k = kappa_hg * 2.0 * el.mu * vol * bb / 3.0;
    let mut hg = [[0.0; 8]; 8];
    for gamma in &gammas {
        for a in 0..8 {
            for b in 0..8 {
                hg[a][b] += k * gamma[a] * gamma[b];
            }
        }
    }
    hg
}
