//! The isotropic small-strain constants every law's parameters convert through: [`Elastic`]
//! (μ, κ), the common currency, and [`Lame`] (λ, μ); each constructible from (E, ν) or
//! (μ, κ), with the conversions between them written once.

use crate::error::{self, MaterialError};
use crate::tensor::Tangent;

/// Isotropic small-strain elastic constants, the common currency for parameter conversion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Elastic {
    /// Shear modulus μ (> 0).
    pub mu: f64,
    /// Bulk modulus κ (> 0).
    pub kappa: f64,
}

impl Elastic {
    /// From Young's modulus `E > 0` and Poisson's ratio `ν ∈ (−1, 0.5)`:
    /// `μ = E / (2(1+ν))`, `κ = E / (3(1−2ν))`.
    pub fn from_young_poisson(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        let young = error::young(young)?;
        let poisson = error::poisson(poisson)?;
        Ok(Elastic {
            mu: young / (2.0 * (1.0 + poisson)),
            kappa: young / (3.0 * (1.0 - 2.0 * poisson)),
        })
    }

    /// From shear modulus `μ > 0` and bulk modulus `κ > 0`.
    pub fn from_mu_kappa(mu: f64, kappa: f64) -> Result<Self, MaterialError> {
        Ok(Elastic { mu: error::shear(mu)?, kappa: error::bulk(kappa)? })
    }

    /// Lamé's first parameter `λ = κ − 2μ/3`.
    pub fn lambda(&self) -> f64 {
        self.kappa - 2.0 * self.mu / 3.0
    }

    /// Young's modulus `E = 9κμ / (3κ + μ)`.
    pub fn young(&self) -> f64 {
        9.0 * self.kappa * self.mu / (3.0 * self.kappa + self.mu)
    }

    /// Poisson's ratio `ν = (3κ − 2μ) / (2(3κ + μ))`.
    pub fn poisson(&self) -> f64 {
        (3.0 * self.kappa - 2.0 * self.mu) / (2.0 * (3.0 * self.kappa + self.mu))
    }

    /// P-wave (dilatational) modulus `λ + 2μ = κ + 4μ/3`; the dilatational wave speed is
    /// `sqrt((λ + 2μ)/ρ)`.
    pub fn p_wave_modulus(&self) -> f64 {
        self.kappa + 4.0 * self.mu / 3.0
    }

    /// The small-strain isotropic elasticity matrix in this crate's Voigt convention.
    pub fn small_strain_tangent(&self) -> Tangent {
        let l = self.lambda();
        let mut d = Tangent::zeros();
        for i in 0..3 {
            for j in 0..3 {
                d[(i, j)] = l;
            }
            d[(i, i)] += 2.0 * self.mu;
            d[(i + 3, i + 3)] = self.mu;
        }
        d
    }
}

/// Parameters of the St Venant–Kirchhoff law (Lamé constants).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lame {
    /// Lamé's first parameter λ.
    pub lambda: f64,
    /// Shear modulus μ.
    pub mu: f64,
}

impl Lame {
    /// From Young's modulus `E > 0` and Poisson's ratio `ν ∈ (−1, 0.5)` (through
    /// [`Elastic::from_young_poisson`]).
    pub fn from_young_poisson(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        Ok(Elastic::from_young_poisson(young, poisson)?.into())
    }

    /// From shear modulus `μ > 0` and bulk modulus `κ > 0`: `λ = κ − 2μ/3`.
    pub fn from_mu_kappa(mu: f64, kappa: f64) -> Result<Self, MaterialError> {
        Ok(Elastic::from_mu_kappa(mu, kappa)?.into())
    }
}

impl From<Elastic> for Lame {
    /// `λ = κ − 2μ/3`, same `μ`.
    fn from(e: Elastic) -> Self {
        Lame { lambda: e.lambda(), mu: e.mu }
    }
}

impl From<Lame> for Elastic {
    /// `κ = λ + 2μ/3`, same `μ`: the small-strain constants of a Lamé pair.
    fn from(l: Lame) -> Self {
        Elastic { mu: l.mu, kappa: l.lambda + 2.0 * l.mu / 3.0 }
    }
}
