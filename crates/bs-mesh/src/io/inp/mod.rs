//! Abaqus / CalculiX input decks (`.inp`): reader and writer.
//!
//! # What the reader understands
//!
//! * `*NODE` (optionally `NSET=`): `id, x[, y[, z]]`; missing coordinates are 0, extra fields
//!   (the optional normal direction) are ignored. Ids may be sparse and in any order.
//! * `*ELEMENT, TYPE=…[, ELSET=…]`: `C3D4` (also the hybrid `C3D4H`) becomes a
//!   [`Tet4`](ElementKind::Tet4); `C3D8`, `C3D8R` (and `C3D8H`, `C3D8RH`, `C3D8I`, `C3D8IH`,
//!   which have the same 8 nodes) become [`Hex8`](ElementKind::Hex8). Quadratic and other 3D
//!   types (`C3D10`, `C3D20`, wedges, pyramids, …) are rejected with the fix. 1D/2D types
//!   (`CPS3`, `CPS4`, `S3`, `S4R`, `T3D2`, `M3D4`, …, the surface elements gmsh writes) are
//!   skipped and their ids dropped from element sets; an element set left empty only because
//!   its members were skipped is dropped. Element lines ending with `,` continue on the next
//!   line.
//! * `*NSET, NSET=…` and `*ELSET, ELSET=…` with id lists (any number per line, set names
//!   allowed as items), with `GENERATE` (`start, end[, step]`; ids in the range that do not
//!   exist are left out), and `*NSET, NSET=…, ELSET=…` (the nodes of an element set).
//!   Sets are resolved after the whole deck is read, so they may come before what they list.
//!   Explicitly listed ids that do not exist are an error.
//! * Keywords and parameters are case-insensitive; set names are kept as first written and
//!   matched case-insensitively (as Abaqus does). `**` comments, blank lines, `*HEADING` and
//!   every other keyword (`*MATERIAL`, `*STEP`, …) with its data lines are skipped.
//!   `*INCLUDE` is an error (the reader sees only this file's bytes).
//!
//! # What the writer produces
//!
//! [`write()`] emits `*NODE`, one `*ELEMENT, TYPE=C3D4` / `TYPE=C3D8` block per run of equal
//! element kinds (a mesh ordered by kind gets one block per kind; element order is kept), then
//! `*NSET` and `*ELSET` blocks with 16 ids per line (fewer when 16 would pass 132
//! characters). The deck is meant for CalculiX too, which reads only the first
//! [`COORD_WIDTH`] = 20 characters of a coordinate (`f20.0`) and at most 132 characters per
//! line. Coordinates are therefore printed with the shortest text that reads back to the same
//! `f64` bits (Rust's round-trip formatting, or the same digits as an integer mantissa with
//! an exponent or without the leading `0`) when that fits in 20 characters, which holds for
//! every value with 0.01 <= |x| < 1e16 and every value of at most 14 significant digits.
//! Otherwise the value is rounded to the most significant digits that fit: at least 14, a
//! relative change below 1e-13.

mod read;
mod write;

pub use read::read;
pub(crate) use read::snippet;
pub use write::{COORD_WIDTH, write};
