//! Intra-operative measurements fitted with the model as the regulariser (`[[measurement]]`):
//! read and checked at preparation ([`read`]), made into bs-fit's data terms at composition
//! ([`terms`], the rigid misalignment estimated from bone there), and summarised after the
//! solve ([`outcome`]: report.json's `measurements`, residuals.csv); a pull that cannot be
//! carried is explained ([`failure`]) and falls back to the prior ([`fallback`]). The numerics (matching,
//! robust weights, the rigid fit) are bs-fit's; this module reads files and names things.

use std::path::PathBuf;

use bs_mesh::Point3;

pub(crate) mod dispatch;
pub(crate) mod failure;
pub(crate) mod fallback;
pub(crate) mod outcome;
pub mod pairs;
pub(crate) mod read;
pub(crate) mod terms;

pub use outcome::{MeasurementKind, MeasurementReport, PointRow, RigidReport};
pub use terms::FitState;

/// One `[[measurement]]` with its files read and its node set resolved.
#[derive(Debug, Clone)]
pub struct Measured {
    /// Its position among the scene's `[[measurement]]` tables (from 0).
    pub index: usize,
    /// The node set it may pull.
    pub nset: String,
    /// The noise (standard deviation), mesh units.
    pub sigma: f64,
    /// Points farther than this from the patch are not matched, mesh units.
    pub max_distance: f64,
    /// Whether a rigid misalignment is estimated (from bone points).
    pub rigid: bool,
    /// The data.
    pub data: MeasuredData,
}

/// What a measurement measured.
#[derive(Debug, Clone)]
pub enum MeasuredData {
    /// A scanned surface.
    Surface {
        /// The point cloud's file.
        file: PathBuf,
        /// Its points (scene frame and units).
        points: Vec<Point3<f64>>,
        /// The boundary faces of the node set (mesh node indices, outward).
        faces: Vec<[usize; 3]>,
        /// The element of each face (its material sets the data stiffness).
        face_elements: Vec<usize>,
        /// Bone points of the same scan, and their file.
        bone: Option<(PathBuf, Vec<Point3<f64>>)>,
        /// The sliding prior: `None` free, else the sag direction (`None`: the patch's mean
        /// inward normal).
        slide: Option<Option<bs_mesh::Vector3<f64>>>,
    },
    /// Landmark pairs.
    Landmarks {
        /// The files they were read from.
        files: crate::scene::LandmarkFiles,
        /// The pairs (scene frame and units) and where each was read.
        pairs: pairs::Pairs,
        /// Per landmark: the element holding its pre-operative position, and its material
        /// point there.
        anchors: Vec<(usize, bs_fit::Anchor)>,
    },
}

impl Measured {
    /// The key of its table in messages (`[[measurement]] #2`).
    pub fn key(&self) -> String {
        format!("[[measurement]] #{}", self.index + 1)
    }

    /// One line for `check`: what was read and what it will pull.
    pub fn note(&self) -> String {
        match &self.data {
            MeasuredData::Surface { file, points, faces, bone, .. } => format!(
                "{} points {}: {} points fitted on {} ({} boundary faces), sigma {}{}",
                self.key(),
                file.display(),
                points.len(),
                self.nset,
                faces.len(),
                self.sigma,
                match bone {
                    Some((f, b)) => format!(
                        ", rigid misalignment from {} bone points of {}",
                        b.len(),
                        f.display()
                    ),
                    None => String::new(),
                }
            ),
            MeasuredData::Landmarks { files, pairs, .. } if self.nset.is_empty() => format!(
                "{} landmarks {}: {} pairs, evidence for gravity's unknowns beside the scan, \
                 sigma {}",
                self.key(),
                files.describe(),
                pairs.pre.len(),
                self.sigma
            ),
            MeasuredData::Landmarks { files, pairs, .. } => format!(
                "{} landmarks {}: {} pairs fitted through {}, sigma {}",
                self.key(),
                files.describe(),
                pairs.pre.len(),
                self.nset,
                self.sigma
            ),
        }
    }
}
