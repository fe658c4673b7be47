//! Placeholder: the inp reader is being written.
use super::{Location, ParseError};
use crate::Mesh;
use std::path::Path;

/// Parses a inp file.
pub fn read(_bytes: &[u8], file: &Path) -> Result<Mesh, ParseError> {
    Err(ParseError::new(file, Location::File, "inp reader not available yet"))
}
