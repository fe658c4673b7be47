//! Registration outputs: a computed brain shift applied to images. The result of a run (the
//! reference mesh and its nodal displacements, `result.vtu`, with the frame and unit from
//! `report.json`) defines the piecewise-linear map X ↦ x = X + u(X) on every tetrahedron. Its
//! exact inverse on an image grid (which reference point X lands on each voxel centre y of
//! the intra-operative configuration) is found by `bs_mesh::lattice`; here the run
//! directory is read, frames and units are reconciled with the image's, and the two
//! outputs are made:
//!
//! * [`InverseMap::warp`]: the pre-operative image resampled into the intra-operative
//!   configuration, `warped(y) = preop(X(y))` (trilinear; nearest for labelmaps); between
//!   the deformed brain and the skull X(y) = y + d(y) with d extended harmonically from the
//!   brain to zero at the skull ([`crate::outside`]); voxels outside the skull cavity keep
//!   their value, bit for bit;
//! * [`InverseMap::field`]: the same map as a displacement field `d(y) = X(y) − y` (zero
//!   outside the skull cavity), the convention of ITK's `DisplacementFieldTransform` (a
//!   resampling transform maps output points to input points), so that ITK or 3D Slicer
//!   resampling the pre-operative image with it gives [`InverseMap::warp`]'s image.
//!
//! Images are in millimetres in their world frame (NIfTI: RAS). A result in metres or in
//! LPS is converted; a mesh that does not lie in the image (wrong frame, wrong image) is an
//! error naming both frames and extents, never an empty warp.

mod files;
mod inverse;
mod nodal;
mod result;

pub use files::*;
pub use inverse::*;
pub use nodal::*;
pub use result::*;
