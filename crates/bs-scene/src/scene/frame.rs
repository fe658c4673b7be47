//! The mesh's length unit and anatomical frame: `units` and `space`.

use serde::Deserialize;

/// Length unit of the mesh files. Stresses and moduli are always in Pa.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
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

/// The anatomical frame of the mesh coordinates (and of every displacement and output).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
pub enum SpaceName {
    /// Right–Anterior–Superior: NIfTI's world frame and 3D Slicer's (the default).
    #[default]
    #[serde(rename = "RAS")]
    Ras,
    /// Left–Posterior–Superior: DICOM's and ITK's frame.
    #[serde(rename = "LPS")]
    Lps,
}

impl SpaceName {
    /// The frame.
    pub fn space(self) -> bs_image::Space {
        match self {
            SpaceName::Ras => bs_image::Space::Ras,
            SpaceName::Lps => bs_image::Space::Lps,
        }
    }
}
