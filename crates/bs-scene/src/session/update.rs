//! What a live session takes, typed and in memory: [`Update`], applied by
//! [`Session::apply`]. Each front end (the OpenIGTLink server, the Python bindings) turns
//! its input into updates; nothing is written to a file and no scene table is read again.

use bs_dr::Progress;
use bs_mesh::Point3;

use super::{BoundaryValues, Session};
use crate::SceneError;
use crate::run::Solved;

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

/// What one call of [`Session::apply`] does, its updates sorted.
struct Plan<'u> {
    boundaries: Vec<(&'u str, &'u BoundaryValues)>,
    scans: Vec<(String, Vec<Point3<f64>>)>,
    landmarks: Option<(&'u str, &'u [Point3<f64>], &'u [Point3<f64>])>,
    gravity: Option<[f64; 3]>,
    resect: Option<&'u str>,
}

impl<'u> Plan<'u> {
    fn of(updates: &'u [Update]) -> Result<Plan<'u>, String> {
        let mut plan =
            Plan { boundaries: Vec::new(), scans: Vec::new(), landmarks: None, gravity: None, resect: None };
        for u in updates {
            match u {
                Update::Boundary { set, values } => plan.boundaries.push((set, values)),
                Update::Scan { set, points } => plan.scans.push((set.clone(), points.clone())),
                Update::Landmarks { set, pre, intra } => {
                    if plan.landmarks.replace((set, pre, intra)).is_some() {
                        return Err("landmarks of one node set per update".into());
                    }
                }
                Update::Gravity(g) => plan.gravity = Some(*g),
                Update::Resect(r) => plan.resect = Some(r),
            }
        }
        let kinds = [!plan.boundaries.is_empty(), !plan.scans.is_empty(), plan.landmarks.is_some(), plan.resect.is_some()];
        if kinds.iter().filter(|&&k| k).count() > 1 || (plan.resect.is_some() && plan.gravity.is_some()) {
            return Err("give new boundary values, new scans, new landmarks or a resection in one \
                        call, not two of them (gravity goes with any but a resection); apply \
                        them one after the other"
                .into());
        }
        Ok(plan)
    }
}

impl Session {
    /// Applies `updates` and solves once, warm from the last good state (a scan or landmarks
    /// from the reference state, as a cold run fits them), verified as a cold run is. New
    /// boundary values of several sets, new scans of several measurements, or one set's
    /// landmarks, each with or without a turned gravity; or a resection alone. An empty list
    /// solves the loads now set. On any error the session keeps its last good state, loads
    /// and direction.
    pub fn apply(
        &mut self,
        updates: &[Update],
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solved, SceneError> {
        let plan = Plan::of(updates).map_err(|message| SceneError::Scene {
            file: self.run.prepared.path.clone(),
            message: format!("update: {message}"),
        })?;
        if let Some(region) = plan.resect {
            return self.resect(region, observer);
        }
        let turned = plan.gravity.map(|g| self.set_gravity(g)).transpose()?;
        let solved = if !plan.scans.is_empty() {
            self.update_points(&plan.scans, observer)
        } else if let Some((set, pre, intra)) = plan.landmarks {
            self.fit_landmarks(set, pre, intra, observer)
        } else if !plan.boundaries.is_empty() {
            self.update_boundaries(&plan.boundaries, observer)
        } else {
            self.solve(observer)
        };
        if let (Err(_), Some(previous)) = (&solved, turned) {
            self.set_gravity(previous).expect("the previous direction was accepted");
        }
        solved
    }
}
