//! Errors of image reading, writing and checking; each names the file and the fix.

use std::path::PathBuf;

/// An image could not be read, written or used.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file could not be opened, read or written.
    #[error("{}: {message}", file.display())]
    Io { file: PathBuf, message: String },
    /// The file is not a usable image of the kind asked for (bad header, wrong dimension,
    /// unsupported datatype, not a labelmap, empty label...). The message says the fix.
    #[error("{}: {message}", file.display())]
    Invalid { file: PathBuf, message: String },
    /// A grid that cannot map voxels to the world (zero size, singular affine, non-finite).
    #[error("invalid image grid: {0}")]
    Grid(String),
}
