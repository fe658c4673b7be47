//! Placeholder: the stl reader/writer is being written.
use super::{Location, ParseError};
use crate::TriSurface;
use std::io::Write;
use std::path::Path;

/// Parses a stl file.
pub fn read(_bytes: &[u8], file: &Path) -> Result<TriSurface, ParseError> {
    Err(ParseError::new(file, Location::File, "stl reader not available yet"))
}

/// Writes a binary STL file.
pub fn write_binary(_w: &mut dyn Write, _s: &TriSurface) -> std::io::Result<()> {
    Err(std::io::Error::other("stl writer not available yet"))
}
