//! `[[measurement]]`: an intra-operative scan or landmark pairs, fitted with the model.

use std::path::PathBuf;

use serde::Deserialize;

/// The landmark files of a `[[measurement]]`: one file of pairs (`.csv` with
/// `x,y,z,x2,y2,z2`, or an MNI `.tag` file with two volumes), or two files of points paired
/// by label (3D Slicer markups `.fcsv` / `.mrk.json`: pre-operative, intra-operative).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum LandmarkFiles {
    /// One file of pairs.
    Pairs(PathBuf),
    /// Pre-operative and intra-operative points, paired by label.
    Split([PathBuf; 2]),
}

impl LandmarkFiles {
    /// The files, comma-separated, for messages and reports.
    pub fn describe(&self) -> String {
        match self {
            LandmarkFiles::Pairs(f) => f.display().to_string(),
            LandmarkFiles::Split([a, b]) => format!("{}, {}", a.display(), b.display()),
        }
    }

    /// The files, for messages and path resolution.
    pub fn files_mut(&mut self) -> Vec<&mut PathBuf> {
        match self {
            LandmarkFiles::Pairs(f) => vec![f],
            LandmarkFiles::Split([a, b]) => vec![a, b],
        }
    }
}

/// Default of a measurement's `max_distance`, in mm: scanned points farther than this from
/// the brain's exposed surface are not matched.
pub const DEFAULT_MEASUREMENT_DISTANCE_MM: f64 = 20.0;

/// An intra-operative measurement fitted with the model as the regulariser (not imposed):
/// a scanned surface or landmark pairs.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measurement {
    /// The exposed brain surface as measured: a point cloud (.csv with columns x,y,z, .ply,
    /// .vtk/.vtp polydata, or the vertices of .stl/.obj/.off), in the scene's frame and units.
    pub points: Option<PathBuf>,
    /// Landmark pairs (pre-operative → intra-operative positions) anywhere in the brain.
    pub landmarks: Option<LandmarkFiles>,
    /// The boundary nodes the measurement may pull (points: the exposed surface; landmarks
    /// fitted alone: where the unknown load acts, the craniotomy, whose displacement the fit
    /// finds; landmarks beside a scan name none: the scan pulls the boundary and the
    /// landmarks are evidence for gravity's unknowns).
    pub nset: Option<String>,
    /// The measurement's noise: the standard deviation of a point's error, mesh units.
    pub sigma: f64,
    /// Points the same scan took on the bone around the window (they do not move): the
    /// evidence for `rigid`.
    pub skull_points: Option<PathBuf>,
    /// Also estimate (and undo) a rigid misalignment of the scan, from `skull_points`.
    #[serde(default)]
    pub rigid: bool,
    /// Scanned points farther than this from the exposed surface are not matched (mesh
    /// units; default 20 mm).
    pub max_distance: Option<f64>,
    /// Whether the scanned patch's sliding along itself (which a scan cannot see) is
    /// resisted by a weak prior or left to the model alone (docs/fit.md). Default: resisted,
    /// or free in a scene with `[gravity]`, whose weight decides the sliding
    /// ([`Measurement::sliding_with`]).
    pub sliding: Option<Sliding>,
    /// The direction the exposed surface sinks along, which the sliding prior leaves free
    /// (scene frame; default: the patch's mean inward normal, into the window).
    pub sag_direction: Option<[f64; 3]>,
}

/// What a scan cannot see, its patch sliding along itself: resisted by a weak prior across
/// the sag direction, or free (decided by the model alone).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sliding {
    /// Displacement across the sag direction resisted as the tissue resists a displacement
    /// of the window's size.
    #[default]
    Resisted,
    /// No prior: the elasticity, the skull and the held nodes alone decide.
    Free,
}

impl Measurement {
    /// The sliding a scan is fitted with in a scene with (`gravity`) or without gravity:
    /// the key's, else free with gravity (docs/fit.md, the sliding study: the prior
    /// resists the sideways sinking gravity causes) unless a `sag_direction` asks for the
    /// prior, else resisted.
    pub fn sliding_with(&self, gravity: bool) -> Sliding {
        match self.sliding {
            Some(s) => s,
            None if gravity && self.sag_direction.is_none() => Sliding::Free,
            None => Sliding::Resisted,
        }
    }

    /// Checks what the types cannot: one kind of data, its keys, positive numbers.
    pub fn validate(&self) -> Result<(), String> {
        match (&self.points, &self.landmarks) {
            (Some(_), Some(_)) | (None, None) => {
                return Err("give exactly one of points (a scanned surface) or landmarks".into());
            }
            (Some(_), None) if self.nset.is_none() => {
                return Err("points needs nset: the boundary nodes the scan may pull (e.g. \
                            nset = \"CRANIOTOMY\")"
                    .into());
            }
            (None, Some(_)) if self.skull_points.is_some() || self.rigid => {
                return Err("skull_points and rigid go with points (a scan), not landmarks".into());
            }
            (None, Some(_)) if self.sliding.is_some() || self.sag_direction.is_some() => {
                return Err(
                    "sliding and sag_direction go with points (a scan), not landmarks".into()
                );
            }
            _ => {}
        }
        if !(self.sigma > 0.0 && self.sigma.is_finite()) {
            return Err(format!(
                "sigma must be positive (the measurement's noise, mesh units), got {}",
                self.sigma
            ));
        }
        if let Some(d) = self.max_distance
            && !(d > 0.0 && d.is_finite())
        {
            return Err(format!("max_distance must be positive (mesh units), got {d}"));
        }
        if let Some(d) = self.sag_direction {
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if !(n > 0.0 && n.is_finite()) {
                return Err(format!(
                    "sag_direction must be a non-zero vector [x, y, z] (scene frame), got {d:?}"
                ));
            }
            if self.sliding == Some(Sliding::Free) {
                return Err("sag_direction is the direction the sliding prior leaves free: \
                            with sliding = \"free\" there is no prior; drop one of them"
                    .into());
            }
        }
        if self.rigid && self.skull_points.is_none() {
            return Err("rigid = true needs skull_points: the misalignment is estimated from \
                        bone, which does not move; fitted to the brain alone it would explain \
                        the shift as misalignment (docs/fit.md)"
                .into());
        }
        if self.skull_points.is_some() && !self.rigid {
            return Err("skull_points are only used to estimate the misalignment: add rigid = \
                        true, or drop skull_points"
                .into());
        }
        Ok(())
    }
}
