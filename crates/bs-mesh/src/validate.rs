//! Mesh validation.

/// A problem found in a mesh.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// Placeholder.
    #[error("placeholder")]
    Placeholder,
}

/// All problems found by validation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ValidationReport {
    /// Problems.
    pub errors: Vec<MeshError>,
}
