//! Meshes from segmentations (labelmaps) for brainshift.
//!
//! [`mesh_labelmap`] turns a labelmap ([`Volume<u32>`]) into a brain mesh with element sets
//! per region and the node sets `FIXED` (the inferior-most surface nodes, the brain stem's
//! cut) and `CRANIOTOMY` (surface nodes near the top), plus a closed outward skull cavity
//! surface around it:
//!
//! * [`implicit`]: smoothed indicator fields from the labels (separable Gaussian),
//!   trilinear evaluation at world points;
//! * [`bcc`], [`stuffing`], [`stencil`]: isosurface stuffing on a BCC lattice (Labelle &
//!   Shewchuk 2007), dihedral angles proven in [10.78°, 164.76°];
//! * [`regions`]: region surfaces cut into the stuffed brain, conforming on both sides;
//! * [`hex`]: voxel-like hexahedra on a grid;
//! * [`cavity`] (with [`edt`]): the skull cavity by offset-and-closing of the brain mask, or
//!   the inside of a skull label;
//! * [`quality`], [`report`]: dihedral angles and the [`MeshReport`];
//! * `pipeline.rs`: `mesh_labelmap` as named phases (labels checked and counted, fields,
//!   the lattice's box and size bound, the volume mesh, sets and quality, the cavity and its
//!   checks, volumes);
//! * `error.rs`: `MeshgenError`, each naming what is wrong and the fix;
//! * `lib.rs` itself: `ElementType`, `RegionSpec`, `MeshParams` and the result `Meshed`.
//!
//! Coordinates are the image's world frame in mm (RAS for NIfTI), as given by the
//! labelmap's [`Grid`](bs_image::Grid).
//!
//! *Architecture invariant:* bs-meshgen knows images and meshes (bs-image, bs-mesh); it
//! knows no materials, solvers, contact or scene files.

pub mod bcc;
pub mod cavity;
pub mod edt;
mod error;
pub mod hex;
pub mod implicit;
mod pipeline;
pub mod quality;
pub mod regions;
pub mod report;
pub mod stencil;
pub mod stuffing;

use std::collections::BTreeSet;

use bs_image::Volume;
use bs_mesh::{Mesh, TriSurface};

pub use error::MeshgenError;
pub use pipeline::mesh_labelmap;
pub use report::{MeshReport, RegionVolume};

use crate::implicit::world_box;

/// Element type of the brain mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ElementType {
    /// Quality tetrahedra by isosurface stuffing (the default).
    #[default]
    T4,
    /// Hexahedra on a regular grid.
    H8,
}

impl ElementType {
    /// `"t4"` or `"h8"`.
    pub fn name(self) -> &'static str {
        match self {
            ElementType::T4 => "t4",
            ElementType::H8 => "h8",
        }
    }

    /// Parses `"t4"` / `"h8"` (case-insensitive).
    pub fn from_name(s: &str) -> Option<ElementType> {
        match s.to_ascii_lowercase().as_str() {
            "t4" => Some(ElementType::T4),
            "h8" => Some(ElementType::H8),
            _ => None,
        }
    }
}

/// A region with its own material: an element set made of the elements on these labels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RegionSpec {
    /// Element set name (written as given, e.g. `VENTRICLES`).
    pub name: String,
    /// Label values.
    pub labels: Vec<u32>,
}

/// The name of the element set holding the brain outside every region.
pub const BRAIN_SET: &str = "BRAIN";
/// The node set held fixed (the inferior-most brain surface, the brain stem's cut).
pub const FIXED_SET: &str = "FIXED";
/// The node set of surface nodes near the top of the brain, for a craniotomy load.
pub const CRANIOTOMY_SET: &str = "CRANIOTOMY";

/// Largest lattice (or grid) size accepted: 50 million vertices, about 2 GB of working
/// memory and far beyond any brain model (1 mm over MNI152 is 9 million).
pub const MAX_LATTICE_VERTICES: f64 = 50e6;

/// How to mesh a labelmap.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshParams {
    /// Labels making up the brain; `None` = every non-zero label.
    pub brain_labels: Option<Vec<u32>>,
    /// Regions with their own material (the rest of the brain is [`BRAIN_SET`]).
    pub regions: Vec<RegionSpec>,
    /// Target edge length, mm: the BCC lattice spacing (long edges; short edges are 0.87×)
    /// or the hexahedron side.
    pub size: f64,
    /// Element type.
    pub element: ElementType,
    /// Distance of the skull cavity outside the brain, mm (ignored with `cavity_labels`);
    /// for H8 measured from the staircase's outer corners (offset + √3/2 `size` from the
    /// smooth brain surface).
    pub skull_offset: f64,
    /// Radius of the ball the offset brain is closed with, mm: the cavity bridges sulci.
    pub closing_radius: f64,
    /// If given, the cavity is the inside of these (skull) labels instead of an offset.
    pub cavity_labels: Option<Vec<u32>>,
    /// Standard deviation of the Gaussian smoothing the indicator, mm; `None` = 0.6 × the
    /// largest voxel size. The blur damps the voxel staircase (a 45° staircase's ripple by
    /// e^(−2π²σ²) ≈ 10⁻³) but moves the ½ level inwards by about σ² × mean curvature (mean
    /// curvature flow for time σ²/2): for a 20 mm ball in 1 mm voxels, −0.3% of volume.
    pub smoothing: Option<f64>,
    /// Lattice spacing of the skull surface, mm; `None` = `size`.
    pub skull_size: Option<f64>,
}

impl Default for MeshParams {
    fn default() -> Self {
        MeshParams {
            brain_labels: None,
            regions: Vec::new(),
            size: 4.0,
            element: ElementType::T4,
            skull_offset: 3.0,
            closing_radius: 5.0,
            cavity_labels: None,
            smoothing: None,
            skull_size: None,
        }
    }
}

/// A meshed labelmap.
#[derive(Debug, Clone)]
pub struct Meshed {
    /// The brain: element sets [`BRAIN_SET`] and one per region, node sets [`FIXED_SET`]
    /// and [`CRANIOTOMY_SET`]; world coordinates in mm.
    pub mesh: Mesh,
    /// The skull cavity: closed, outward, without self-intersections, the brain inside.
    pub skull: TriSurface,
    /// Measurements.
    pub report: MeshReport,
}

pub(crate) fn check_params(labels: &Volume<u32>, p: &MeshParams) -> Result<(), MeshgenError> {
    let positive = |name: &'static str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(MeshgenError::Param {
                name,
                message: format!("{v} must be a positive number of mm"),
            })
        }
    };
    positive("--size", p.size)?;
    positive("--skull-offset", p.skull_offset)?;
    positive("closing radius", p.closing_radius)?;
    if let Some(s) = p.smoothing.filter(|s| !(s.is_finite() && *s >= 0.0)) {
        return Err(MeshgenError::Param {
            name: "smoothing",
            message: format!("{s} must be ≥ 0 mm"),
        });
    }
    if let Some(s) = p.skull_size {
        positive("skull size", s)?;
    }
    let extent = {
        let (lo, hi) = world_box(&labels.grid);
        (hi - lo).norm()
    };
    if p.size > extent {
        return Err(MeshgenError::Param {
            name: "--size",
            message: format!(
                "{} mm exceeds the image's extent ({extent:.0} mm); give a smaller size",
                p.size
            ),
        });
    }
    if p.brain_labels.as_ref().is_some_and(|b| b.contains(&0)) {
        return Err(MeshgenError::Labels(
            "label 0 is the background and cannot be part of --brain; list the brain's label values".into(),
        ));
    }
    let mut seen = BTreeSet::new();
    let mut names = BTreeSet::new();
    for r in &p.regions {
        if r.name.is_empty()
            || !r.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            return Err(MeshgenError::Region {
                region: r.name.clone(),
                message: "a region name must be non-empty letters, digits, '_' or '-' (it names an element set)".into(),
            });
        }
        if r.name.eq_ignore_ascii_case(BRAIN_SET) || !names.insert(r.name.to_ascii_uppercase()) {
            return Err(MeshgenError::Region {
                region: r.name.clone(),
                message: "the name is used twice (BRAIN is the rest of the brain); give each region its own name".into(),
            });
        }
        if r.labels.is_empty() {
            return Err(MeshgenError::Region {
                region: r.name.clone(),
                message: "no labels given; write NAME=4 or NAME=4,5".into(),
            });
        }
        for &l in &r.labels {
            if l == 0 {
                return Err(MeshgenError::Region {
                    region: r.name.clone(),
                    message: "label 0 is the background".into(),
                });
            }
            if p.brain_labels.as_ref().is_some_and(|b| !b.contains(&l)) {
                return Err(MeshgenError::Region {
                    region: r.name.clone(),
                    message: format!("label {l} is not part of --brain; add it to --brain"),
                });
            }
            if !seen.insert(l) {
                return Err(MeshgenError::Region {
                    region: r.name.clone(),
                    message: format!("label {l} belongs to two regions; give it to one"),
                });
            }
        }
    }
    Ok(())
}
