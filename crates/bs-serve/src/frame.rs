//! Geometry on the wire is RAS millimetres (3D Slicer's world frame); the scene has its own
//! frame (RAS or LPS) and length unit (mm or m). [`Frame`] converts points and directions
//! both ways; displacement CSV rows are in the scene's frame and unit already, as a
//! `displacement_file` is.

use bs_image::Space;
use bs_mesh::{Point3, Vector3};
use bs_scene::scene::Units;

/// The scene's frame and unit against RAS mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    space: Space,
    /// Millimetres per scene unit.
    mm: f64,
}

impl Frame {
    /// The frame of a scene with `space` and `units`.
    pub fn new(space: Space, units: Units) -> Frame {
        Frame { space, mm: units.metres() / 1e-3 }
    }

    /// A RAS mm point in the scene's frame and unit.
    pub fn to_scene(&self, ras_mm: [f64; 3]) -> Point3<f64> {
        Space::Ras.convert_point(self.space, Point3::from(ras_mm)) / self.mm
    }

    /// A scene point in RAS mm.
    pub fn to_ras(&self, p: &Point3<f64>) -> [f64; 3] {
        (self.space.convert_point(Space::Ras, *p) * self.mm).coords.into()
    }

    /// A RAS direction in the scene's frame (no unit: directions keep their length).
    pub fn direction_to_scene(&self, d: Vector3<f64>) -> [f64; 3] {
        Space::Ras.convert_vector(self.space, d).into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lps_metres_and_back() {
        let f = Frame::new(Space::Lps, Units::M);
        assert_eq!(f.to_scene([1000.0, -2000.0, 3000.0]), Point3::new(-1.0, 2.0, 3.0));
        assert_eq!(f.to_ras(&f.to_scene([1.5, 2.5, -3.5])), [1.5, 2.5, -3.5]);
        let ras = Frame::new(Space::Ras, Units::Mm);
        assert_eq!(ras.to_scene([1.0, 2.0, 3.0]), Point3::new(1.0, 2.0, 3.0));
        assert_eq!(f.direction_to_scene(Vector3::new(0.0, -1.0, 0.0)), [0.0, 1.0, 0.0]);
    }
}
