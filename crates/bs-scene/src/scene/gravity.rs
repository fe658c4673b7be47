//! The `[gravity]` table: the tissue's weight and the fluid that buoys it.

use serde::Deserialize;

/// Standard gravity (m/s²), the default of `[gravity] acceleration`.
pub const STANDARD_GRAVITY: f64 = 9.81;

/// The `[gravity]` table: the tissue's weight, and the cerebrospinal fluid that buoys it
/// where it has not drained.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gravity {
    /// Gravity's direction in the scene's frame (any length but zero): a supine patient's
    /// in RAS is `[0, -1, 0]` (posterior).
    pub direction: [f64; 3],
    /// Acceleration [m/s²]; default 9.81.
    #[serde(default = "standard_gravity")]
    pub acceleration: f64,
    /// The fluid below a level: there the tissue weighs `(ρ − ρ_fluid) g`, above it `ρ g`.
    pub fluid: Option<Fluid>,
    /// The parameters the fit estimates from the measurements, with their priors.
    pub estimate: Option<Estimate>,
}

/// `[gravity] estimate`: which of gravity's unknowns a fit estimates with the data, each
/// with the standard deviation of its prior around the scene's value (docs/fit.md).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Estimate {
    /// The fluid's level along gravity (mesh units): where the fluid stands after drainage.
    pub level: Option<f64>,
    /// Gravity's direction (degrees): the head pose the navigation tracks, to a few degrees.
    pub direction: Option<f64>,
    /// The tissue's effective weight against its stiffness (a fraction of the weight).
    pub weight: Option<f64>,
}

impl Estimate {
    /// Each named parameter and its prior standard deviation, in the order level, direction,
    /// weight.
    pub fn named(&self) -> Vec<(&'static str, f64)> {
        [("level", self.level), ("direction", self.direction), ("weight", self.weight)]
            .into_iter()
            .filter_map(|(k, v)| v.map(|v| (k, v)))
            .collect()
    }
}

fn standard_gravity() -> f64 {
    STANDARD_GRAVITY
}

/// A fluid filling the space below a level (cerebrospinal fluid drained above it).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fluid {
    /// Density [kg/m³] (cerebrospinal fluid: 1007).
    pub density: f64,
    /// A point of the fluid's surface (the plane through it normal to gravity), scene frame
    /// and units.
    pub level: [f64; 3],
}

impl Gravity {
    /// The unit direction (`None` for a zero or non-finite one).
    pub fn unit(&self) -> Option<[f64; 3]> {
        let [x, y, z] = self.direction;
        let n = (x * x + y * y + z * z).sqrt();
        (n > 0.0 && n.is_finite()).then(|| self.direction.map(|c| c / n))
    }

    /// Checks what the types cannot.
    pub fn validate(&self) -> Result<(), String> {
        if self.unit().is_none() {
            return Err(format!(
                "[gravity] direction {:?} has no direction: give a non-zero vector in the scene's \
                 frame (a supine patient in RAS: [0, -1, 0])",
                self.direction
            ));
        }
        if !(self.acceleration >= 0.0 && self.acceleration.is_finite()) {
            return Err(format!(
                "[gravity] acceleration must be finite and ≥ 0 (m/s², default 9.81), got {}",
                self.acceleration
            ));
        }
        if let Some(f) = &self.fluid {
            if !(f.density > 0.0 && f.density.is_finite()) {
                return Err(format!(
                    "[gravity] fluid.density must be positive (kg/m³; cerebrospinal fluid 1007), \
                     got {}",
                    f.density
                ));
            }
            if !f.level.iter().all(|c| c.is_finite()) {
                return Err("[gravity] fluid.level must be a finite point [x, y, z]".into());
            }
        }
        if let Some(e) = &self.estimate {
            self.validate_estimate(e)?;
        }
        Ok(())
    }

    /// The estimate's own checks: something named, positive priors, a level only with a
    /// fluid, a weight only with an acceleration.
    fn validate_estimate(&self, e: &Estimate) -> Result<(), String> {
        let named = e.named();
        if named.is_empty() {
            return Err("[gravity] estimate names nothing: give one or more of level (mm along \
                        gravity), direction (degrees) and weight (a fraction), each the \
                        standard deviation of its prior"
                .into());
        }
        for (key, sd) in &named {
            if !(*sd > 0.0 && sd.is_finite()) {
                return Err(format!(
                    "[gravity] estimate.{key} = {sd}: a prior's standard deviation must be \
                     positive and finite (level in mesh units, direction in degrees, weight a \
                     fraction); remove the key to keep the scene's value"
                ));
            }
        }
        if e.level.is_some() && self.fluid.is_none() {
            return Err("[gravity] estimate.level: there is no fluid whose level to estimate; \
                        add fluid = { density = 1007.0, level = [x, y, z] } or remove \
                        estimate.level"
                .into());
        }
        if e.direction.is_some_and(|d| d >= 90.0) {
            return Err(format!(
                "[gravity] estimate.direction = {}: the prior is in degrees and must be below \
                 90 (the navigation knows the head's pose to a few degrees)",
                e.direction.unwrap_or_default()
            ));
        }
        if self.acceleration == 0.0 {
            return Err("[gravity] estimate: acceleration = 0 leaves no weight to estimate \
                        anything of; remove estimate or give the acceleration"
                .into());
        }
        Ok(())
    }
}
