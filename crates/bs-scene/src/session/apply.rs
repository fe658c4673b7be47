//! [`Session::apply`]: one call's updates sorted (what may go together) and applied, the
//! session solved once.

use bs_dr::Progress;
use bs_mesh::Point3;

use super::Session;
use super::update::{BoundaryValues, Update};
use crate::SceneError;
use crate::run::Solved;

/// One set's landmark pairs: the set, pre- and intra-operative positions.
type Pairs<'u> = (&'u str, &'u [Point3<f64>], &'u [Point3<f64>]);

/// What one call of [`Session::apply`] does, its updates sorted.
struct Plan<'u> {
    boundaries: Vec<(&'u str, &'u BoundaryValues)>,
    scans: Vec<(String, Vec<Point3<f64>>)>,
    landmarks: Option<Pairs<'u>>,
    gravity: Option<[f64; 3]>,
    resect: Option<&'u str>,
}

impl<'u> Plan<'u> {
    fn of(updates: &'u [Update]) -> Result<Plan<'u>, String> {
        let mut plan = Plan {
            boundaries: Vec::new(),
            scans: Vec::new(),
            landmarks: None,
            gravity: None,
            resect: None,
        };
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
        let kinds = [
            !plan.boundaries.is_empty(),
            !plan.scans.is_empty(),
            plan.landmarks.is_some(),
            plan.resect.is_some(),
        ];
        if kinds.iter().filter(|&&k| k).count() > 1
            || (plan.resect.is_some() && plan.gravity.is_some())
        {
            return Err(
                "give new boundary values, new scans, new landmarks or a resection in one \
                        call, not two of them (gravity goes with any but a resection); apply \
                        them one after the other"
                    .into(),
            );
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
