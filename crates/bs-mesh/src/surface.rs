//! Triangle surfaces and their topology.

use nalgebra::{Point3, Vector3};

/// A triangle surface mesh. Triangles are counter-clockwise seen from outside when the
/// surface is outward oriented.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriSurface {
    /// Vertex coordinates.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[usize; 3]>,
}
