//! Placeholder: the obj reader/writer is being written.
use super::{Location, ParseError};
use crate::TriSurface;
use std::io::Write;
use std::path::Path;

/// Parses a obj file.
pub fn read(_bytes: &[u8], file: &Path) -> Result<TriSurface, ParseError> {
    Err(ParseError::new(file, Location::File, "obj reader not available yet"))
}

/// Writes the surface.
pub fn write(_w: &mut dyn Write, _s: &TriSurface) -> std::io::Result<()> {
    Err(std::io::Error::other("writer not available yet"))
}
