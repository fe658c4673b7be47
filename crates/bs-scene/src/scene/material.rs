//! `[mesh] element` and `[[region]]`: element choices, materials and their moduli.

use serde::{Deserialize, Serialize};

/// Element technology.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ElementChoice {
    /// Linear tetrahedron.
    #[default]
    T4,
    /// Linear tetrahedron with average nodal pressure (locking-free).
    T4anp,
    /// Mean-strain hexahedron with hourglass control.
    H8,
}

impl ElementChoice {
    /// Every technology, in the order tables list them.
    pub const ALL: [ElementChoice; 3] =
        [ElementChoice::T4, ElementChoice::T4anp, ElementChoice::H8];

    /// The name used in scene files, reports and tables (`"t4"`, `"t4anp"`, `"h8"`).
    pub fn name(self) -> &'static str {
        match self {
            ElementChoice::T4 => "t4",
            ElementChoice::T4anp => "t4anp",
            ElementChoice::H8 => "h8",
        }
    }

    /// The technology of a name (the inverse of [`ElementChoice::name`]).
    pub fn from_name(name: &str) -> Option<ElementChoice> {
        ElementChoice::ALL.into_iter().find(|e| e.name() == name)
    }

    /// The mesh element kind this technology needs.
    pub fn mesh_kind(self) -> bs_mesh::ElementKind {
        match self {
            ElementChoice::H8 => bs_mesh::ElementKind::Hex8,
            ElementChoice::T4 | ElementChoice::T4anp => bs_mesh::ElementKind::Tet4,
        }
    }

    /// The solver's tetrahedral formulation (H8 meshes have no tetrahedra; T4ANP is the
    /// model's default there).
    pub fn tet_formulation(self) -> bs_dr::TetFormulation {
        match self {
            ElementChoice::T4 => bs_dr::TetFormulation::T4,
            ElementChoice::T4anp | ElementChoice::H8 => bs_dr::TetFormulation::T4Anp,
        }
    }
}

/// Constitutive model names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MaterialModel {
    /// Decoupled Neo-Hookean.
    NeoHookean,
    /// St Venant–Kirchhoff ("linear elastic" in a Total Lagrangian code).
    Svk,
    /// One-term Ogden.
    Ogden,
}

impl MaterialModel {
    /// The scene-file name (`"neo-hookean"`, `"svk"`, `"ogden"`).
    pub fn name(self) -> &'static str {
        match self {
            MaterialModel::NeoHookean => "neo-hookean",
            MaterialModel::Svk => "svk",
            MaterialModel::Ogden => "ogden",
        }
    }
}

display_by_name!(ElementChoice, MaterialModel);

/// A material: moduli from (E, ν) or (μ, κ), in Pa; density in kg/m³.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Constitutive model.
    pub model: MaterialModel,
    /// Young's modulus E [Pa].
    pub youngs_modulus: Option<f64>,
    /// Poisson's ratio ν.
    pub poisson_ratio: Option<f64>,
    /// Shear modulus μ [Pa] (alternative to E, ν).
    pub shear_modulus: Option<f64>,
    /// Bulk modulus κ [Pa] (alternative to E, ν).
    pub bulk_modulus: Option<f64>,
    /// Ogden exponent α (Ogden only).
    pub alpha: Option<f64>,
    /// Mass density [kg/m³]: the weight under `[gravity]` (required there); without gravity
    /// only Dynamic Relaxation's masses use it (default 1000).
    pub density: Option<f64>,
}

/// The density Dynamic Relaxation's masses use when a scene without gravity gives none
/// (kg/m³; the masses are fictitious, so any positive value serves).
pub const DEFAULT_DENSITY: f64 = 1000.0;

impl Material {
    /// The density given, or [`DEFAULT_DENSITY`].
    pub fn density_or_default(&self) -> f64 {
        self.density.unwrap_or(DEFAULT_DENSITY)
    }
}

/// Shear and bulk moduli resolved from a [`Material`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moduli {
    /// Shear modulus μ [Pa].
    pub mu: f64,
    /// Bulk modulus κ [Pa].
    pub kappa: f64,
}

impl Material {
    /// Resolves (μ, κ) from whichever pair was given, checking ranges.
    pub fn moduli(&self) -> Result<Moduli, String> {
        match (self.youngs_modulus, self.poisson_ratio, self.shear_modulus, self.bulk_modulus) {
            (Some(e), Some(nu), None, None) => {
                if !(e > 0.0 && e.is_finite()) {
                    return Err(format!("youngs_modulus must be positive, got {e}"));
                }
                if !(nu > -1.0 && nu < 0.5) {
                    return Err(format!(
                        "poisson_ratio must lie in (-1, 0.5), got {nu}; brain tissue is nearly \
                         incompressible, e.g. 0.49"
                    ));
                }
                Ok(Moduli { mu: e / (2.0 * (1.0 + nu)), kappa: e / (3.0 * (1.0 - 2.0 * nu)) })
            }
            (None, None, Some(mu), Some(kappa)) => {
                if !(mu > 0.0 && kappa > 0.0 && mu.is_finite() && kappa.is_finite()) {
                    return Err(format!(
                        "shear_modulus and bulk_modulus must be positive, got {mu} and {kappa}"
                    ));
                }
                Ok(Moduli { mu, kappa })
            }
            _ => Err("give either youngs_modulus and poisson_ratio, or shear_modulus and \
                      bulk_modulus (in Pa)"
                .into()),
        }
    }
}

/// A region: an element set and its material.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// Element set name in the mesh file; `"*"` means every element.
    pub elset: String,
    /// The material.
    pub material: Material,
    /// Resected: the region's elements leave the model (default false).
    #[serde(default)]
    pub resected: bool,
    /// With `resected`: the fluid pressure on the cavity's walls (Pa; default 0).
    pub cavity_pressure: Option<f64>,
}
