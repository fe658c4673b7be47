//! Images for brainshift: a regular voxel grid with its map to world coordinates in mm
//! (`Grid`), voxel data on it (`Volume<T>`), the anatomical frame of world coordinates
//! (`Space`: RAS, the NIfTI world frame, or LPS, the DICOM/ITK one), file formats (NIfTI-1
//! `.nii`/`.nii.gz` and NRRD `.nrrd`/`.nhdr` read and written, chosen by name in
//! [`formats`]; MetaImage `.mha` written), sampling, and the harmonic extension of a field
//! into part of a grid ([`extend`]).
//!
//! Voxel data are stored with the first index fastest: `data[i + nx * (j + ny * k)]`, as
//! in NIfTI files.
//!
//! *Architecture invariant:* bs-image knows no meshes, materials, solvers or contact: it
//! sees grids, voxels and points.

mod error;
pub mod extend;
pub mod formats;
mod grid;
pub mod mask;
mod mha;
pub mod nifti;
pub mod nrrd;
pub mod sample;
mod slice;
mod space;

pub use error::ImageError;
pub use grid::{Grid, Volume};
pub use mha::write_displacement_mha;
pub use slice::Slice;
pub use space::Space;
