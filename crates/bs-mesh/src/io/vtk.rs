//! Placeholder: the vtk reader/writer is being written.
use super::{Fields, Location, ParseError};
use crate::Mesh;
use std::io::Write;
use std::path::Path;

/// Parses a vtk file.
pub fn read(_bytes: &[u8], file: &Path) -> Result<(Mesh, Fields), ParseError> {
    Err(ParseError::new(file, Location::File, "vtk reader not available yet"))
}

/// Writes a legacy VTK file.
pub fn write(_w: &mut dyn Write, _mesh: &Mesh, _fields: &Fields) -> std::io::Result<()> {
    Err(std::io::Error::other("vtk writer not available yet"))
}
