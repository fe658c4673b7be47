//! `[[boundary]]`: the nodes a boundary selects and what it prescribes.

use std::path::PathBuf;

use serde::Deserialize;

/// A displacement component.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Component {
    /// x
    X,
    /// y
    Y,
    /// z
    Z,
}

impl Component {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        self as usize
    }
}

/// Final prescribed displacement values; unnamed components stay free.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Displacement {
    /// x component.
    pub x: Option<f64>,
    /// y component.
    pub y: Option<f64>,
    /// z component.
    pub z: Option<f64>,
}

impl Displacement {
    /// As an array of optional components.
    pub fn components(&self) -> [Option<f64>; 3] {
        [self.x, self.y, self.z]
    }
}

/// A sphere selecting the mesh's boundary nodes inside it (a craniotomy without a node set).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sphere {
    /// Centre, mesh frame and units.
    pub centre: [f64; 3],
    /// Radius, mesh units.
    pub radius: f64,
}

/// Default of `max_distance` (surface loads) and `max_extrapolation` (landmark loads), in mm.
pub const DEFAULT_MAX_DISTANCE_MM: f64 = 10.0;

/// A boundary condition on a node set (or from a file).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Boundary {
    /// Node set name in the mesh file.
    pub nset: Option<String>,
    /// Instead of `nset`: the mesh's boundary nodes inside this sphere.
    pub sphere: Option<Sphere>,
    /// Instead of `nset`: the mesh's boundary nodes whose nearest voxel of this NIfTI image
    /// is non-zero (the image's world frame, mm).
    pub mask: Option<PathBuf>,
    /// Components held at zero.
    pub fix: Option<Vec<Component>>,
    /// Final displacement on the 3-4-5 ramp.
    pub displacement: Option<Displacement>,
    /// CSV with `node_id,ux,uy,uz` per prescribed node (relative to the scene file).
    pub displacement_file: Option<PathBuf>,
    /// Intra-operative surface (.stl, .obj, .off; mesh frame and units): each selected node
    /// moves to its closest point on it.
    pub surface: Option<PathBuf>,
    /// Largest node-to-surface distance accepted (mesh units; default 10 mm).
    pub max_distance: Option<f64>,
    /// CSV of landmark pairs `x,y,z,x2,y2,z2` (pre-operative, intra-operative; mesh frame and
    /// units): the selected nodes move by the thin-plate spline of the landmark displacements.
    pub landmarks: Option<PathBuf>,
    /// Largest distance of a selected node outside the landmarks' bounding box (mesh units;
    /// default 10 mm).
    pub max_extrapolation: Option<f64>,
}
