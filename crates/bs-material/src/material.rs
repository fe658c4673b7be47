//! [`Material`]: a law and its parameters chosen at run time (what a scene file names), and
//! its constructors from (E, ν) or (μ, κ) for every law.

use nalgebra::Matrix3;

use crate::elastic::{Elastic, Lame};
use crate::error::MaterialError;
use crate::law::Hyperelastic;
use crate::neo_hookean::NeoHookean;
use crate::ogden::{Ogden, OgdenParams};
use crate::st_venant_kirchhoff::StVenantKirchhoff;
use crate::tensor::{Tangent, kinematics};

/// A law with its parameters, chosen at run time (what a scene file names).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    /// [`NeoHookean`].
    NeoHookean(Elastic),
    /// [`StVenantKirchhoff`].
    StVenantKirchhoff(Lame),
    /// [`Ogden`].
    Ogden(OgdenParams),
}

impl Material {
    /// Neo-Hookean from `(E, ν)`.
    pub fn neo_hookean(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        Ok(Material::NeoHookean(Elastic::from_young_poisson(young, poisson)?))
    }

    /// Neo-Hookean from `(μ, κ)`.
    pub fn neo_hookean_mu_kappa(mu: f64, kappa: f64) -> Result<Self, MaterialError> {
        Ok(Material::NeoHookean(Elastic::from_mu_kappa(mu, kappa)?))
    }

    /// St Venant–Kirchhoff from `(E, ν)`.
    pub fn st_venant_kirchhoff(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        Ok(Material::StVenantKirchhoff(Lame::from_young_poisson(young, poisson)?))
    }

    /// St Venant–Kirchhoff from `(μ, κ)`.
    pub fn st_venant_kirchhoff_mu_kappa(mu: f64, kappa: f64) -> Result<Self, MaterialError> {
        Ok(Material::StVenantKirchhoff(Lame::from_mu_kappa(mu, kappa)?))
    }

    /// One-term Ogden from `(E, ν)` and the exponent `α`.
    pub fn ogden(young: f64, poisson: f64, alpha: f64) -> Result<Self, MaterialError> {
        Ok(Material::Ogden(OgdenParams::from_young_poisson(young, poisson, alpha)?))
    }

    /// One-term Ogden from `(μ, κ)` and the exponent `α`.
    pub fn ogden_mu_kappa(mu: f64, kappa: f64, alpha: f64) -> Result<Self, MaterialError> {
        Ok(Material::Ogden(OgdenParams::from_mu_kappa(mu, kappa, alpha)?))
    }

    /// Short name (`"neo-hookean"`, `"st-venant-kirchhoff"`, `"ogden"`).
    pub fn name(&self) -> &'static str {
        match self {
            Material::NeoHookean(_) => "neo-hookean",
            Material::StVenantKirchhoff(_) => "st-venant-kirchhoff",
            Material::Ogden(_) => "ogden",
        }
    }

    /// Small-strain constants at `F = I` (for wave speeds and critical time steps).
    pub fn elastic(&self) -> Elastic {
        match self {
            Material::NeoHookean(e) => *e,
            Material::StVenantKirchhoff(l) => Elastic::from(*l),
            Material::Ogden(o) => o.elastic(),
        }
    }

    /// Unchecked energy kernel, see [`Hyperelastic::energy_cj`].
    pub fn energy_cj(&self, c: &Matrix3<f64>, j: f64) -> f64 {
        match self {
            Material::NeoHookean(p) => NeoHookean::energy_cj(p, c, j),
            Material::StVenantKirchhoff(p) => StVenantKirchhoff::energy_cj(p, c, j),
            Material::Ogden(p) => Ogden::energy_cj(p, c, j),
        }
    }

    /// Unchecked stress kernel, see [`Hyperelastic::pk2_cj`].
    #[inline]
    pub fn pk2_cj(&self, c: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        match self {
            Material::NeoHookean(p) => NeoHookean::pk2_cj(p, c, j),
            Material::StVenantKirchhoff(p) => StVenantKirchhoff::pk2_cj(p, c, j),
            Material::Ogden(p) => Ogden::pk2_cj(p, c, j),
        }
    }

    /// Unchecked first Piola–Kirchhoff kernel, see [`Hyperelastic::pk1_fj`].
    #[inline]
    pub fn pk1_fj(&self, f: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        match self {
            Material::NeoHookean(p) => NeoHookean::pk1_fj(p, f, j),
            Material::StVenantKirchhoff(p) => StVenantKirchhoff::pk1_fj(p, f, j),
            Material::Ogden(p) => Ogden::pk1_fj(p, f, j),
        }
    }

    /// Unchecked tangent kernel, see [`Hyperelastic::tangent_cj`].
    pub fn tangent_cj(&self, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent) {
        match self {
            Material::NeoHookean(p) => NeoHookean::tangent_cj(p, c, j),
            Material::StVenantKirchhoff(p) => StVenantKirchhoff::tangent_cj(p, c, j),
            Material::Ogden(p) => Ogden::tangent_cj(p, c, j),
        }
    }

    /// Checked energy `W(F)`.
    pub fn energy(&self, f: &Matrix3<f64>) -> Result<f64, MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(self.energy_cj(&c, j))
    }

    /// Checked stress `S(F)`.
    pub fn pk2(&self, f: &Matrix3<f64>) -> Result<Matrix3<f64>, MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(self.pk2_cj(&c, j))
    }

    /// Checked `S(F)` and tangent.
    pub fn tangent(&self, f: &Matrix3<f64>) -> Result<(Matrix3<f64>, Tangent), MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(self.tangent_cj(&c, j))
    }
}
