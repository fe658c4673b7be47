//! The mesh's length unit, `units` (its anatomical frame, `space`, is `bs_image::Space`).

use serde::{Deserialize, Serialize};

/// Length unit of the mesh files. Stresses and moduli are always in Pa.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Units {
    /// Millimetres.
    Mm,
    /// Metres.
    M,
}

impl Units {
    /// Metres per mesh length unit.
    pub fn metres(self) -> f64 {
        match self {
            Units::Mm => 1e-3,
            Units::M => 1.0,
        }
    }

    /// The unit's symbol.
    pub fn symbol(self) -> &'static str {
        match self {
            Units::Mm => "mm",
            Units::M => "m",
        }
    }
}
