//! Gmsh meshes (`.msh`), versions 4.1 and 2.2 (2.0 and 2.1 read as 2.2), ASCII or binary.
//!
//! * The version and file type come from `$MeshFormat`; versions 1, 3 and 4.0 are rejected
//!   with the fix. Binary files (file type 1, either byte order) are read by
//!   `binary.rs` into the same [`Mesh`] as the ASCII file of the same mesh (`ascii.rs`);
//!   their errors name byte offsets instead of lines. Both build the mesh through
//!   `state.rs`.
//! * `$PhysicalNames`, `$Entities` (4.1: which physical groups each entity belongs to),
//!   `$Nodes` and `$Elements` are read; every other section (`$Periodic`, `$NodeData`, …) is
//!   skipped. `$Nodes` must come before `$Elements` (gmsh always writes it so). Partitioned
//!   4.1 files (`$PartitionedEntities`) are rejected: save without partitions.
//! * Element types 4 (4-node tetrahedron) and 5 (8-node hexahedron) become elements; gmsh's
//!   node orders for both equal the Abaqus/VTK orders used by [`Mesh`]. Other 3D types
//!   (second-order tets 11, hexes 12/17, prisms, pyramids) are rejected with the fix.
//!   Points, lines, triangles and quadrangles (types 15, 1, 2, 3 and their higher-order
//!   versions) are not elements; their nodes go into the node sets of their physical groups.
//! * Physical groups become sets: a 3D group becomes an element set named by its physical
//!   name (`PHYSICAL_<tag>` when unnamed) and a node set of its elements' nodes; a 0D/1D/2D
//!   group becomes a node set of its elements' nodes (`PHYSICAL_<dim>D_<tag>` when unnamed,
//!   so that it cannot merge with a 3D group of the same tag). Groups of any dimension that
//!   share a name share the set.
//! * Version 2.2 writes an element once per physical group it belongs to (same tag and
//!   nodes); such repeats add group membership. Any other repeated node or element tag is an
//!   error naming both lines.

mod ascii;
mod binary;
mod state;

use std::path::Path;

use crate::Mesh;
use crate::io::inp::snippet;
use crate::io::{Location, ParseError};

/// The supported file layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Version {
    V2,
    V4,
}

/// What the `$MeshFormat` header says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Header {
    /// File layout version.
    pub(super) version: Version,
    /// File type 1 (binary) rather than 0 (ASCII).
    pub(super) binary: bool,
    /// The data-size field: bytes of a `size_t` in binary 4.1 files (4 or 8).
    pub(super) data_size: usize,
    /// Byte offset just past the header line (where a binary file's endianness int starts).
    pub(super) end: usize,
}

/// Reads the version and file type from the `$MeshFormat` header straight from the bytes, so
/// that binary files (not UTF-8) are recognised before any text decoding.
fn sniff(bytes: &[u8], file: &Path) -> Result<Header, ParseError> {
    let err = |line, msg: String| ParseError::new(file, Location::Line(line), msg);
    let mut rest = crate::io::strip_bom(bytes);
    let total = bytes.len();
    let mut line_no = 0;
    let mut next_line = || -> Option<&[u8]> {
        loop {
            if rest.is_empty() {
                return None;
            }
            let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            let l = &rest[..end];
            rest = &rest[(end + 1).min(rest.len())..];
            line_no += 1;
            if !l.trim_ascii().is_empty() {
                return Some(l.trim_ascii());
            }
        }
    };
    let first = next_line();
    if first != Some(b"$MeshFormat".as_slice()) {
        return Err(ParseError::new(
            file,
            Location::Line(1),
            "expected '$MeshFormat' on the first line: this is not a gmsh .msh file (or it is \
             gmsh 1.0, which is not supported: save as version 4.1 or 2.2)",
        ));
    }
    let header = next_line();
    let ln = line_no;
    let end = total - rest.len();
    let header = header.and_then(|h| std::str::from_utf8(h).ok()).ok_or_else(|| {
        err(ln, "expected 'version file-type data-size' (e.g. '4.1 0 8') after $MeshFormat".into())
    })?;
    let mut f = header.split_ascii_whitespace();
    let version = f.next().unwrap_or("");
    let file_type = f.next().unwrap_or("");
    let binary = match file_type {
        "0" => false,
        "1" => true,
        _ => {
            let msg = format!(
                "expected file-type 0 (ASCII) or 1 (binary) in '{}' (format 'version file-type \
                 data-size')",
                snippet(header)
            );
            return Err(err(ln, msg));
        }
    };
    let data_size = match f.next().map(str::parse::<usize>) {
        Some(Ok(n @ (4 | 8))) => n,
        _ if !binary => 8,
        _ => {
            return Err(err(
                ln,
                format!(
                    "expected data-size 4 or 8 (bytes of size_t) in '{}'; re-save the binary \
                     file with gmsh on a 32- or 64-bit machine",
                    snippet(header)
                ),
            ));
        }
    };
    let version = match version {
        "4.1" => Version::V4,
        "2" | "2.0" | "2.1" | "2.2" => Version::V2,
        v => {
            return Err(err(
                ln,
                format!(
                    "gmsh format version '{}' is not supported; save as 4.1 or 2.2 ASCII (`gmsh \
                 mesh.msh -save -format msh41 -o new.msh`)",
                    snippet(v)
                ),
            ));
        }
    };
    Ok(Header { version, binary, data_size, end })
}

/// Parses a gmsh `.msh` file (4.1 or 2.2, ASCII or binary). See the [module docs](self).
pub fn read(bytes: &[u8], file: &Path) -> Result<Mesh, ParseError> {
    let header = sniff(bytes, file)?;
    if header.binary { binary::read(bytes, file, header) } else { ascii::read(bytes, file, header) }
}
