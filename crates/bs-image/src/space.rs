//! The anatomical frame of world coordinates.

use nalgebra::{Point3, Vector3};

/// The anatomical frame world coordinates (mm) are given in.
///
/// The one frame type of the workspace: scene files (`space = "RAS"`), reports and VTU
/// `SPACE` field data spell it `"RAS"` / `"LPS"` (serde and [`Space::name`]), and every
/// RAS ↔ LPS conversion is [`Space::convert_point`] / [`Space::convert_vector`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub enum Space {
    /// The NIfTI world frame and 3D Slicer's: +x = Right, +y = Anterior, +z = Superior (the
    /// default).
    #[default]
    #[serde(rename = "RAS")]
    Ras,
    /// DICOM / ITK frame: +x = Left, +y = Posterior, +z = Superior.
    #[serde(rename = "LPS")]
    Lps,
}

impl Space {
    /// "RAS" or "LPS", as written in scene files, VTU `SPACE` field data and reports.
    pub fn name(self) -> &'static str {
        match self {
            Space::Ras => "RAS",
            Space::Lps => "LPS",
        }
    }

    /// Parses "RAS" / "LPS" (case-insensitive).
    pub fn from_name(s: &str) -> Option<Space> {
        match s.to_ascii_uppercase().as_str() {
            "RAS" => Some(Space::Ras),
            "LPS" => Some(Space::Lps),
            _ => None,
        }
    }

    /// A point of this frame expressed in `to` (RAS ↔ LPS negates x and y).
    pub fn convert_point(self, to: Space, p: Point3<f64>) -> Point3<f64> {
        if self == to { p } else { Point3::new(-p.x, -p.y, p.z) }
    }

    /// A vector (displacement) of this frame expressed in `to`.
    pub fn convert_vector(self, to: Space, v: Vector3<f64>) -> Vector3<f64> {
        if self == to { v } else { Vector3::new(-v.x, -v.y, v.z) }
    }
}

/// Reads `"RAS"` / `"LPS"` (exact spelling, as written); anything else is refused with the
/// value quoted and the two frames named, e.g. `space "RAI" is not a frame brainshift
/// knows: use "RAS" (NIfTI, 3D Slicer) or "LPS" (DICOM, ITK)`.
impl<'de> serde::Deserialize<'de> for Space {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Space, D::Error> {
        let s = String::deserialize(d)?;
        match s.as_str() {
            "RAS" => Ok(Space::Ras),
            "LPS" => Ok(Space::Lps),
            _ => Err(serde::de::Error::custom(format!(
                "space {s:?} is not a frame brainshift knows: use \"RAS\" (NIfTI, 3D Slicer) or \"LPS\" (DICOM, ITK)"
            ))),
        }
    }
}
