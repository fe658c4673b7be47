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
        Ok(())
    }
}
