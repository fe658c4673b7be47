//! The one-term Ogden law (parameters: [`OgdenParams`]).

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use crate::elastic::Elastic;
use crate::error::{self, MaterialError};
use crate::law::Hyperelastic;
use crate::tensor::{Tangent, VOIGT, add_outer};

/// Parameters of the one-term Ogden law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OgdenParams {
    /// Initial shear modulus μ (> 0).
    pub mu: f64,
    /// Exponent α (≠ 0; brain tissue: −4.7).
    pub alpha: f64,
    /// Bulk modulus κ (> 0).
    pub kappa: f64,
}

impl OgdenParams {
    /// Validated parameters.
    pub fn new(mu: f64, alpha: f64, kappa: f64) -> Result<Self, MaterialError> {
        let mu = error::shear(mu)?;
        let alpha = error::ogden_exponent(alpha)?;
        let kappa = error::bulk(kappa)?;
        Ok(OgdenParams { mu, alpha, kappa })
    }

    /// From initial shear modulus `μ > 0`, bulk modulus `κ > 0` and exponent `α ≠ 0` (the
    /// same as [`new`](Self::new), with the arguments in the order of the other laws'
    /// `from_mu_kappa`).
    pub fn from_mu_kappa(mu: f64, kappa: f64, alpha: f64) -> Result<Self, MaterialError> {
        Self::new(mu, alpha, kappa)
    }

    /// From Young's modulus `E > 0`, Poisson's ratio `ν ∈ (−1, 0.5)` (the small-strain
    /// constants, [`Elastic::from_young_poisson`]) and exponent `α ≠ 0`.
    pub fn from_young_poisson(young: f64, poisson: f64, alpha: f64) -> Result<Self, MaterialError> {
        let e = Elastic::from_young_poisson(young, poisson)?;
        Self::new(e.mu, alpha, e.kappa)
    }

    /// From initial shear modulus, exponent and Poisson's ratio (κ from μ and ν).
    pub fn from_mu_alpha_poisson(mu: f64, alpha: f64, poisson: f64) -> Result<Self, MaterialError> {
        let poisson = error::poisson(poisson)?;
        let kappa = 2.0 * mu * (1.0 + poisson) / (3.0 * (1.0 - 2.0 * poisson));
        Self::new(mu, alpha, kappa)
    }

    /// Brain-tissue parameters of the literature (Miller & Chinzei): μ = 842 Pa, α = −4.7,
    /// with the given Poisson's ratio.
    pub fn brain(poisson: f64) -> Result<Self, MaterialError> {
        Self::from_mu_alpha_poisson(842.0, -4.7, poisson)
    }

    /// Small-strain constants (μ, κ).
    pub fn elastic(&self) -> Elastic {
        Elastic { mu: self.mu, kappa: self.kappa }
    }
}

/// One-term Ogden law, decoupled:
/// `W = 2μ/α² (λ̄₁^α + λ̄₂^α + λ̄₃^α − 3) + κ/2 (J − 1)²` with `λ̄ᵢ = J^(−1/3) λᵢ` and `λᵢ` the
/// principal stretches. Written in the eigenvalues `cᵢ = λᵢ²` of `C`:
/// `W = 2μ/α² (J^(−α/3) Σ cᵢ^(α/2) − 3) + κ/2 (J−1)²`; stress and tangent by the spectral
/// formulas for isotropic functions of `C` (with the coalescent-eigenvalue limit).
#[derive(Debug, Clone, Copy, Default)]
pub struct Ogden;

impl Ogden {
    /// `S_a = 2 ∂W/∂c_a` and `H_ab = ∂S_a/∂c_b` for eigenvalues `c` of C.
    fn principal(
        p: &OgdenParams,
        c: &Vector3<f64>,
        j: f64,
    ) -> (Vector3<f64>, nalgebra::Matrix3<f64>) {
        let al = p.alpha;
        let k = 2.0 * p.mu / (al * al);
        let jm = j.powf(-al / 3.0);
        let pw = c.map(|x| x.powf(al / 2.0)); // c_a^(α/2)
        let sum: f64 = pw.sum();
        // ∂J/∂c_a = J / (2 c_a); ∂(J^(−α/3))/∂c_a = −α/3 J^(−α/3) / (2 c_a)
        // W_iso = k (jm Σ − 3)
        // ∂W_iso/∂c_a = k jm (α/2 pw_a / c_a − α/6 Σ / c_a) = k jm α/2 (pw_a − Σ/3)/c_a
        // W_vol' = κ (J−1) J/(2 c_a)
        let mut sa = Vector3::zeros();
        for a in 0..3 {
            let dw = k * jm * al * 0.5 * (pw[a] - sum / 3.0) / c[a]
                + p.kappa * (j - 1.0) * j / (2.0 * c[a]);
            sa[a] = 2.0 * dw;
        }
        // H_ab = ∂S_a/∂c_b.
        // S_a = k jm α (pw_a − Σ/3)/c_a + κ (J² − J)/c_a
        // ∂jm/∂c_b = −α/6 jm / c_b; ∂pw_a/∂c_b = δ_ab α/2 pw_a / c_a; ∂Σ/∂c_b = α/2 pw_b / c_b
        // ∂(J²−J)/∂c_b = (2J² − J)/(2 c_b)
        let mut h = nalgebra::Matrix3::zeros();
        for a in 0..3 {
            for b in 0..3 {
                let dab = if a == b { 1.0 } else { 0.0 };
                let t = pw[a] - sum / 3.0;
                let dt = dab * al * 0.5 * pw[a] / c[a] - al / 6.0 * pw[b] / c[b];
                let iso = k
                    * al
                    * (-al / 6.0 * jm / c[b] * t / c[a] + jm * dt / c[a]
                        - dab * jm * t / (c[a] * c[a]));
                let vol = p.kappa
                    * ((2.0 * j * j - j) / (2.0 * c[b]) / c[a] - dab * (j * j - j) / (c[a] * c[a]));
                h[(a, b)] = iso + vol;
            }
        }
        (sa, h)
    }
}

impl Hyperelastic for Ogden {
    type Params = OgdenParams;

    fn energy_cj(p: &OgdenParams, c: &Matrix3<f64>, j: f64) -> f64 {
        let eig = SymmetricEigen::new(*c);
        let al = p.alpha;
        let sum: f64 = eig.eigenvalues.iter().map(|&x| x.max(0.0).powf(al / 2.0)).sum();
        2.0 * p.mu / (al * al) * (j.powf(-al / 3.0) * sum - 3.0)
            + 0.5 * p.kappa * (j - 1.0) * (j - 1.0)
    }

    fn pk2_cj(p: &OgdenParams, c: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        let eig = SymmetricEigen::new(*c);
        let cv = eig.eigenvalues;
        let (sa, _) = Self::principal(p, &cv, j);
        let n = &eig.eigenvectors;
        let mut s = Matrix3::zeros();
        for a in 0..3 {
            let v = n.column(a);
            s += v * v.transpose() * sa[a];
        }
        s
    }

    fn tangent_cj(p: &OgdenParams, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent) {
        // S = Σ S_a N_a⊗N_a; ∂S/∂C = Σ_ab H_ab N_a N_a N_b N_b
        //   + Σ_{a≠b} (S_a − S_b)/(c_a − c_b) · ½ (N_a⊗N_b⊗N_a⊗N_b + N_a⊗N_b⊗N_b⊗N_a),
        // ℂ = 2 ∂S/∂C. For (nearly) equal c_a, c_b the quotient is replaced by its limit
        // H_aa − H_ab (exact for a symmetric function of the eigenvalues).
        let eig = SymmetricEigen::new(*c);
        let cv = eig.eigenvalues;
        let (sa, h) = Self::principal(p, &cv, j);
        let n = eig.eigenvectors;
        let na: [Vector3<f64>; 3] = [n.column(0).into(), n.column(1).into(), n.column(2).into()];
        let mut s = Matrix3::zeros();
        for a in 0..3 {
            s += na[a] * na[a].transpose() * sa[a];
        }
        let mut d = Tangent::zeros();
        let scale = cv.abs().max();
        for a in 0..3 {
            let ma = na[a] * na[a].transpose();
            for b in 0..3 {
                let mb = na[b] * na[b].transpose();
                add_outer(&mut d, 2.0 * h[(a, b)], &ma, &mb);
                if a != b {
                    let dc = cv[a] - cv[b];
                    let q = if dc.abs() > 1e-6 * scale {
                        (sa[a] - sa[b]) / dc
                    } else {
                        // limit of the divided difference
                        0.5 * ((h[(a, a)] - h[(a, b)]) + (h[(b, b)] - h[(b, a)]))
                    };
                    // 2 · q · ½ (N_a N_b N_a N_b + N_a N_b N_b N_a) in Voigt form
                    for (r, &(i, jj)) in VOIGT.iter().enumerate() {
                        for (qq, &(k, l)) in VOIGT.iter().enumerate() {
                            let t = na[a][i] * na[b][jj] * na[a][k] * na[b][l]
                                + na[a][i] * na[b][jj] * na[b][k] * na[a][l];
                            // symmetrise in (i, j) for the stress index
                            let t2 = na[a][jj] * na[b][i] * na[a][l] * na[b][k]
                                + na[a][jj] * na[b][i] * na[b][l] * na[a][k];
                            d[(r, qq)] += q * 0.5 * (t + t2);
                        }
                    }
                }
            }
        }
        (s, d)
    }
}
