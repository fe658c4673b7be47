//! The typed errors of the laws and the parameter checks, written once: every constructor of
//! every law validates through these functions.

/// Errors of the constitutive laws.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum MaterialError {
    /// The deformation gradient has `det F ≤ 0` (or a non-finite determinant): the material
    /// point is inverted or collapsed.
    #[error(
        "inverted material point: det F = {j:e} (must be > 0); the element is inverted or \
         collapsed — check the mesh orientation, reduce the load or the time step"
    )]
    NonPositiveJacobian {
        /// The offending `det F`.
        j: f64,
    },
    /// A material parameter is out of its admissible range.
    #[error("invalid material parameter {name} = {value}: {requirement}")]
    InvalidParameter {
        /// Which parameter (displays as `E`, `nu`, `mu`, `kappa`, `alpha`).
        name: Parameter,
        /// The value given.
        value: f64,
        /// What the parameter must satisfy.
        requirement: &'static str,
    },
}

/// A material parameter, as named in error messages and scene files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Parameter {
    /// Young's modulus `E`.
    Young,
    /// Poisson's ratio `ν` (`nu`).
    Poisson,
    /// Shear modulus `μ` (`mu`).
    Shear,
    /// Bulk modulus `κ` (`kappa`).
    Bulk,
    /// Ogden exponent `α` (`alpha`).
    OgdenExponent,
}

impl Parameter {
    /// The short name (`"E"`, `"nu"`, `"mu"`, `"kappa"`, `"alpha"`).
    pub fn as_str(self) -> &'static str {
        match self {
            Parameter::Young => "E",
            Parameter::Poisson => "nu",
            Parameter::Shear => "mu",
            Parameter::Bulk => "kappa",
            Parameter::OgdenExponent => "alpha",
        }
    }
}

impl std::fmt::Display for Parameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl PartialEq<&str> for Parameter {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}

fn check(
    name: Parameter,
    value: f64,
    ok: bool,
    requirement: &'static str,
) -> Result<f64, MaterialError> {
    if ok && value.is_finite() {
        Ok(value)
    } else {
        Err(MaterialError::InvalidParameter { name, value, requirement })
    }
}

/// `E > 0` (finite).
pub(crate) fn young(e: f64) -> Result<f64, MaterialError> {
    check(Parameter::Young, e, e > 0.0, "Young's modulus must be > 0")
}

/// `−1 < ν < 0.5`.
pub(crate) fn poisson(nu: f64) -> Result<f64, MaterialError> {
    check(Parameter::Poisson, nu, nu > -1.0 && nu < 0.5, "Poisson's ratio must lie in (-1, 0.5)")
}

/// `μ > 0` (finite).
pub(crate) fn shear(mu: f64) -> Result<f64, MaterialError> {
    check(Parameter::Shear, mu, mu > 0.0, "shear modulus must be > 0")
}

/// `κ > 0` (finite).
pub(crate) fn bulk(kappa: f64) -> Result<f64, MaterialError> {
    check(Parameter::Bulk, kappa, kappa > 0.0, "bulk modulus must be > 0")
}

/// `α ≠ 0` (finite).
pub(crate) fn ogden_exponent(alpha: f64) -> Result<f64, MaterialError> {
    check(Parameter::OgdenExponent, alpha, alpha != 0.0, "Ogden exponent must be non-zero")
}
