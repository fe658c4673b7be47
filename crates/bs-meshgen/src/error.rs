//! Errors of meshing a labelmap; each names what is wrong and the fix.

/// A labelmap could not be meshed.
#[derive(Debug, thiserror::Error)]
pub enum MeshgenError {
    /// A parameter is out of range (the message names it and the valid range).
    #[error("invalid meshing parameter {name}: {message}")]
    Param {
        /// The parameter (as the command line spells it, e.g. `--size`).
        name: &'static str,
        /// What is wrong and the fix.
        message: String,
    },
    /// A label asked for is absent from the image, or the brain domain is empty.
    #[error("labelmap: {0}")]
    Labels(String),
    /// A region's labels are not all part of the brain, or two regions share a label.
    #[error("region '{region}': {message}")]
    Region {
        /// The region name.
        region: String,
        /// What is wrong and the fix.
        message: String,
    },
    /// The mesh or the skull failed a check it must pass (closed, outward, brain inside
    /// the skull, no inverted element). The message says what and a likely fix.
    #[error("{what}: {message}")]
    Check {
        /// The checked object (`brain mesh`, `skull surface`).
        what: &'static str,
        /// What failed and the fix.
        message: String,
    },
}
