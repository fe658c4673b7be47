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
//! Files:
//! * `grid.rs`: `Grid` (dimensions and voxel-to-world affine) and `Volume<T>`;
//! * `space.rs`: `Space` (RAS or LPS) with the point and vector conversions;
//! * `error.rs`: `ImageError`, each naming the file and the fix;
//! * `nifti.rs`: NIfTI-1 read (sform, else qform; a file with neither refused) and written
//!   (float32 images, labelmaps, 5-D displacement fields), with its `Header`;
//! * `nrrd.rs`: NRRD `.nrrd`, `.nhdr` and 3D Slicer's `.seg.nrrd` read, and written in LPS;
//! * `mha.rs`: MetaImage displacement fields written in LPS (`write_displacement_mha`);
//! * `formats.rs`: `read_image`, `read_labels`, `write_image`, `write_labels`,
//!   `write_displacement`, the format chosen by file name;
//! * `sample.rs`: trilinear and nearest sampling, labels outside a set, `settle_within`;
//! * `mask.rs`: whether a voxel of a binary mask, or a face neighbour, is set;
//! * `slice.rs`: `Slice`, a plane of numbers for a picture;
//! * `extend/`: `harmonic_extension` of a vector field into the free voxels: `mod.rs` (the
//!   double-precision residual and the refinement rounds), `stencil.rs` (the 7-point
//!   Laplacian), `pcg.rs` (Jacobi-preconditioned CG in single precision), `coarse.rs` (the
//!   first guess on the grid coarsened by two), `folding.rs` (det(I + ∇d)) and `tests.rs`.
//!
//! *Architecture invariant:* bs-image knows no meshes, materials, solvers or contact: it
//! sees grids, voxels and points. Its one brainshift dependency is bs-atomic.

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
