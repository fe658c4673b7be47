//! What a live session takes, typed and in memory: [`Update`] (applied by
//! `Session::apply`, `apply.rs`) and [`BoundaryValues`]. Each front end (the OpenIGTLink
//! server, the Python bindings) turns its input into updates; nothing is written to a file
//! and no scene table is read again.

use bs_mesh::{Point3, TriSurface, Vector3};

/// New values for a prescribed boundary.
#[derive(Debug, Clone, PartialEq)]
pub enum BoundaryValues {
    /// The same displacement for every node of the set (mesh frame and units); only the
    /// components the boundary prescribes may be non-zero.
    Uniform(Vector3<f64>),
    /// One displacement per node, in the order of `Session::set_nodes`.
    PerNode(Vec<Vector3<f64>>),
    /// An intra-operative surface (mesh frame and units): each node moves to its closest
    /// point on it.
    Surface(TriSurface),
}

/// One new measurement or change of the operating room.
#[derive(Debug, Clone, PartialEq)]
pub enum Update {
    /// New values of the prescribed boundary on node set `set`.
    Boundary {
        /// The boundary's node set.
        set: String,
        /// Its values.
        values: BoundaryValues,
    },
    /// A new scan of the `[[measurement]]` with points on node set `set` (scene frame and
    /// units, before the scene's rigid correction): fitted.
    Scan {
        /// The measurement's node set.
        set: String,
        /// The scanned points.
        points: Vec<Point3<f64>>,
    },
    /// Landmark pairs on node set `set` (scene frame and units): fitted, through a landmark
    /// measurement's set or a prescribed boundary's (`landmarks.rs`).
    Landmarks {
        /// The node set the shift comes through.
        set: String,
        /// Pre-operative positions.
        pre: Vec<Point3<f64>>,
        /// Their intra-operative positions.
        intra: Vec<Point3<f64>>,
    },
    /// Gravity's new direction (scene frame; the head repositioned).
    Gravity([f64; 3]),
    /// The region whose element set this is leaves the model.
    Resect(String),
}
