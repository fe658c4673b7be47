//! Placeholder: the vtu reader/writer is being written.
use super::{Fields, Location, ParseError};
use crate::Mesh;
use std::io::Write;
use std::path::Path;

/// Parses a vtu file.
pub fn read(_bytes: &[u8], file: &Path) -> Result<(Mesh, Fields), ParseError> {
    Err(ParseError::new(file, Location::File, "vtu reader not available yet"))
}

/// How VTU data arrays are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// Base64 binary inside each DataArray.
    Inline,
    /// Raw binary in an AppendedData section.
    Appended,
}

/// Writes a VTU file.
pub fn write(
    _w: &mut dyn Write,
    _mesh: &Mesh,
    _fields: &Fields,
    _enc: Encoding,
) -> std::io::Result<()> {
    Err(std::io::Error::other("vtu writer not available yet"))
}
