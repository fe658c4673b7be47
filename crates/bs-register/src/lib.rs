//! Registration: a computed brain shift applied to images. A run's result (`result.vtu`,
//! `report.json`, `skull.off`, as `brainshift run` writes them) defines the map from the
//! pre-operative to the intra-operative configuration; here it is inverted exactly on an
//! image grid, extended between brain and skull, and used to warp images and labelmaps, to
//! export the displacement field ITK and 3D Slicer apply, and to cut the planes a preview
//! shows.
//!
//! * [`registration`]: reading a result, the inverse map, the warp and the field (files and
//!   in memory): `registration/result.rs` (`RunResult`: result.vtu and report.json read
//!   back, in the image's frame and mm), `registration/inverse.rs` (`InverseMap`: the exact
//!   inverse on an image grid, the warp, the labels, the field),
//!   `registration/files.rs` (`warp_file`, `field_file`, `warp_volume`, `field_volume`:
//!   the entry points on files and volumes), `registration/nodal.rs` (`NodalImage`: a nodal
//!   quantity such as σ on an image grid);
//! * [`outside`]: the map between the deformed brain and the skull (harmonic extension,
//!   the pre-operative gap a voxel may sample, the cavity of a resection);
//! * [`planes`]: the three planes through the largest displacement a preview draws.
//!
//! *Architecture invariant:* bs-register reads what a run wrote (bs-scene's `RunReport`
//! and error type) and images (bs-image); it knows no solver, contact or scene schema
//! beyond a result's frame and unit, and nothing in bs-scene depends on it.

pub mod outside;
pub mod planes;
pub mod registration;
