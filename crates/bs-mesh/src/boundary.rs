//! Boundary surface of a volume mesh.
use crate::TriSurface;

/// The outward boundary of a volume mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BoundarySurface {
    /// The surface; its vertices are a subset of the volume nodes.
    pub surface: TriSurface,
    /// Volume node index of each surface vertex.
    pub volume_node: Vec<usize>,
    /// Volume element index of each surface triangle.
    pub element: Vec<usize>,
}
