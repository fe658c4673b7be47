//! `[uncertainty]`: what `run --uncertainty` may use beyond the fit's own posterior.

use serde::Deserialize;

use super::LandmarkFiles;

/// Landmark pairs the fit does not see, whose misses scale σ where the model's own error
/// exceeds what the data's noise explains (docs/uncertainty.md).
///
/// ```toml
/// [uncertainty]
/// held_out = "held-out.csv"   # pairs x,y,z,x2,y2,z2, an MNI .tag, or two Slicer markups
/// sigma = 1.0                 # their localisation noise per axis, mesh units
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UncertaintySection {
    /// The held-out pairs (pre-operative → intra-operative, the scene's frame), in any
    /// form a `[[measurement]]`'s `landmarks` takes. They must not also be fitted.
    pub held_out: LandmarkFiles,
    /// The noise of a held-out pair's displacement per axis (mesh units): the part of
    /// their misses that is not the fit's error.
    pub sigma: f64,
}

impl UncertaintySection {
    /// Checks what the types cannot: a positive finite noise.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.sigma > 0.0 && self.sigma.is_finite()) {
            return Err(format!(
                "[uncertainty] sigma must be positive (the held-out landmarks' noise per \
                 axis, mesh units), got {}",
                self.sigma
            ));
        }
        Ok(())
    }
}
