//! Placeholder: the msh reader is being written.
use super::{Location, ParseError};
use crate::Mesh;
use std::path::Path;

/// Parses a msh file.
pub fn read(_bytes: &[u8], file: &Path) -> Result<Mesh, ParseError> {
    Err(ParseError::new(file, Location::File, "msh reader not available yet"))
}
