//! VTK XML unstructured grids (`.vtu`).
//!
//! Writer: `header_type="UInt64"`, little-endian, points `Float64`, connectivity and offsets
//! `Int64`, types `UInt8` (10 tetrahedron, 12 hexahedron). Point data: every point [`Field`]
//! (`Float64`), plus `node_id` (`Int64`, [`Mesh::node_ids`]) and one `UInt8` array
//! `nset:<NAME>` per node set (1 = member). Cell data likewise with `element_id` and
//! `elset:<NAME>`. [`Encoding::Inline`] writes `format="binary"` base64 data arrays;
//! [`Encoding::Appended`] writes them into `<AppendedData encoding="base64">`, each array's
//! block being base64 of (header + data) with its offset counted in the encoded stream.
//!
//! Reader: ASCII, inline binary and appended (base64 or raw) data, `UInt32` or `UInt64`
//! headers, zlib-compressed data (`vtkZLibDataCompressor`, the default of ParaView and
//! meshio), every integer and float array type. The `node_id`, `element_id`, `nset:` and
//! `elset:` arrays are mapped back, so write→read round trips exactly. Without `node_id` /
//! `element_id`, ids are 0-based positions (VTK convention; a cell's id is its index among
//! all cells of the file). Surface and line cells are skipped; voxels become hexahedra;
//! other volume cells (wedges, quadratic elements…) are errors naming the cell.
//!
//! `cells.rs` holds the cell model shared with the legacy VTK reader (typed arrays, the
//! assembly of a `Mesh` from VTK cells, the checks before writing), `write.rs` the writer,
//! `read.rs` the XML reader.

mod cells;
mod read;
mod write;

pub(crate) use cells::{Array, Cells, Data, assemble, check_for_write, points_of};
pub use read::{read, read_polydata_points};
pub use write::write;

/// How VTU data arrays are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// Base64 binary inside each DataArray (`format="binary"`).
    Inline,
    /// Base64 binary in an `<AppendedData encoding="base64">` section (`format="appended"`).
    Appended,
}
