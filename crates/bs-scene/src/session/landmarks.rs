//! New landmark pairs in a live session, fitted as the scene's landmark measurements are
//! (crate::inverse: through the boundary the shift comes from), never imposed node by node:
//!
//! * on the node set of a landmark `[[measurement]]`, its pairs are replaced (read from files,
//!   or given in memory);
//! * on the node set of a prescribed `[[boundary]]` that holds all three components (the
//!   craniotomy of a scene that prescribes it), that boundary becomes, until the next update
//!   of boundary values, the control set of a landmark measurement with the pairs sent and
//!   noise [`SESSION_LANDMARK_SIGMA_MM`]: the same fit as a cold run of the scene with that
//!   `[[boundary]]` replaced by a `[[measurement]]` with these landmarks.
//!
//! Either fit starts from the reference state, as a cold run does, so the two agree (a
//! landmark fit is several model solves from the reference anyway: its Jacobian's). A
//! landmark fit beside another measurement (a scan) is refused: the scene's own
//! preparation refuses that combination too (crate::measure::read).

use std::path::PathBuf;

use bs_dr::Progress;
use bs_mesh::Point3;

use super::{MeasuredKind, Session};
use crate::SceneError;
use crate::measure::pairs::Pairs;
use crate::measure::{Measured, MeasuredData};
use crate::run::Solved;
use crate::scene::LandmarkFiles;

/// The noise of landmarks sent to a session on a boundary's node set (mm): a tracked
/// pointer's or ultrasound feature's, 1 mm (design notes §10: tracking errors of 1.7–2.2 mm
/// for surfaces, landmarks matched by hand about 1 mm).
pub(crate) const SESSION_LANDMARK_SIGMA_MM: f64 = 1.0;

impl Session {
    /// The node sets of the scene's landmark measurements: the sets whose landmarks
    /// replace a measurement's pairs (landmarks on a boundary's set are fitted too).
    pub fn landmark_sets(&self) -> Vec<&str> {
        self.sets_of(MeasuredKind::Landmarks)
    }

    /// Replaces the pairs of the landmark measurement on node set `name` by those read from
    /// `files` (a `.csv` of x,y,z,x2,y2,z2 or an MNI `.tag`, or two markups files; the
    /// scene's frame conventions) and fits them from the reference state. On any error the
    /// session keeps its last good state and pairs.
    pub fn update_landmarks(
        &mut self,
        name: &str,
        files: LandmarkFiles,
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solved, SceneError> {
        let k = self.landmark_measurement(name)?;
        let p = &self.run.prepared;
        let key = format!("update landmarks[\"{name}\"]");
        let pairs =
            crate::measure::pairs::read_pairs(&files, p.scene.space).map_err(|message| {
                SceneError::Read { scene: p.path.clone(), key: key.clone(), message }
            })?;
        self.refit(k, files, pairs, observer)
    }

    /// Fits the landmark pairs `pre` → `intra` (scene frame and units) on node set `name`:
    /// a landmark measurement's, or a prescribed boundary's (see the module documentation).
    /// On any error the session keeps its last good state.
    pub fn fit_landmarks(
        &mut self,
        name: &str,
        pre: &[Point3<f64>],
        intra: &[Point3<f64>],
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solved, SceneError> {
        let p = &self.run.prepared;
        let key = format!("update landmarks[\"{name}\"]");
        let err =
            |message: String| SceneError::Read { scene: p.path.clone(), key: key.clone(), message };
        if pre.len() != intra.len() || pre.is_empty() {
            return Err(err(format!(
                "{} pre-operative and {} intra-operative landmarks: give pairs, at least one",
                pre.len(),
                intra.len()
            )));
        }
        if let Some(i) = pre.iter().chain(intra).position(|q| !q.iter().all(|x| x.is_finite())) {
            return Err(err(format!("landmark coordinate {i} is not finite")));
        }
        let origin = (1..=pre.len()).map(|k| format!("landmark {k}")).collect();
        let pairs = Pairs { pre: pre.to_vec(), intra: intra.to_vec(), origin };
        let files = LandmarkFiles::Pairs(PathBuf::from("the landmarks sent"));
        if let Ok(k) = self.landmark_measurement(name) {
            return self.refit(k, files, pairs, observer);
        }
        let k = self.add_boundary_fit(name, files.clone())?;
        self.refit(k, files, pairs, observer).inspect_err(|_| {
            self.drop_boundary_fit();
        })
    }

    /// Adds a landmark measurement on the boundary of node set `name` (pairs set by
    /// [`Session::refit`]); its index.
    fn add_boundary_fit(&mut self, name: &str, files: LandmarkFiles) -> Result<usize, SceneError> {
        let set = self.set_load(name)?.clone();
        let p = &self.run.prepared;
        let err = |message: String| SceneError::Set {
            scene: p.path.clone(),
            key: format!("update landmarks[\"{name}\"]"),
            set: name.to_string(),
            message,
        };
        if self.boundary_fit.is_none() && !p.measurements.is_empty() {
            return Err(err("the scene fits other measurements; landmarks are fitted alone in \
                            this version (a scene's preparation refuses the same combination)"
                .into()));
        }
        if set.components != [true; 3] {
            return Err(err("the boundary prescribes only some components; landmarks are \
                            fitted through a boundary that holds all three (x, y, z)"
                .into()));
        }
        if let Some(k) = self.boundary_fit {
            return Ok(k);
        }
        let measured = Measured {
            index: p.measurements.len(),
            nset: name.to_string(),
            sigma: SESSION_LANDMARK_SIGMA_MM * 1e-3 / p.scene.units.metres(),
            max_distance: crate::scene::DEFAULT_MEASUREMENT_DISTANCE_MM * 1e-3
                / p.scene.units.metres(),
            rigid: false,
            data: MeasuredData::Landmarks { files, pairs: Pairs::default(), anchors: Vec::new() },
        };
        self.run.prepared.measurements.push(measured);
        let k = self.run.prepared.measurements.len() - 1;
        self.boundary_fit = Some(k);
        Ok(k)
    }

    /// Removes the landmark measurement a boundary's landmarks added; returns it and the
    /// composed fit it had, for [`Session::restore_boundary_fit`].
    pub(crate) fn drop_boundary_fit(
        &mut self,
    ) -> Option<(Measured, Option<crate::measure::FitState>)> {
        let k = self.boundary_fit.take()?;
        let m = self.run.prepared.measurements.remove(k);
        let fit = std::mem::take(&mut self.run.composed.fit);
        Some((m, fit))
    }

    /// Puts back what [`Session::drop_boundary_fit`] removed.
    pub(crate) fn restore_boundary_fit(
        &mut self,
        dropped: Option<(Measured, Option<crate::measure::FitState>)>,
    ) {
        if let Some((m, fit)) = dropped {
            self.run.prepared.measurements.push(m);
            self.boundary_fit = Some(self.run.prepared.measurements.len() - 1);
            self.run.composed.fit = fit;
        }
    }

    /// Puts `pairs` (read from `files`) in landmark measurement `k`'s place and fits them
    /// from the reference state; on an error everything is as it was.
    fn refit(
        &mut self,
        k: usize,
        files: LandmarkFiles,
        pairs: Pairs,
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solved, SceneError> {
        let p = &self.run.prepared;
        let name = &p.measurements[k].nset;
        let key = format!("update landmarks[\"{name}\"]");
        let anchors = crate::measure::read::locate_landmarks(
            &p.path, &p.scene, &p.mesh, &key, &files, &pairs,
        )?;
        let new = MeasuredData::Landmarks { files, pairs, anchors };
        let previous = std::mem::replace(&mut self.run.prepared.measurements[k].data, new);
        // The data terms as a cold run composes them (a landmark measurement is its scene's
        // only one: no scan's rigid fit is estimated again).
        let fit = match crate::measure::terms::compose_fits(&self.run.prepared) {
            Ok(fit) => fit,
            Err(e) => {
                self.run.prepared.measurements[k].data = previous;
                return Err(e);
            }
        };
        let previous_fit = std::mem::replace(&mut self.run.composed.fit, fit);
        let previous_loads = self.run.prepared.prescribed.clone();
        let warm = std::mem::replace(&mut self.warm, false);
        match self.solve(observer) {
            Ok(solved) => Ok(solved),
            Err(e) => {
                self.warm = warm;
                self.run.prepared.measurements[k].data = previous;
                self.run.composed.fit = previous_fit;
                let _ = self.set_loads(previous_loads);
                Err(e)
            }
        }
    }

    /// The pairs of the landmark measurement on node set `name` now.
    pub fn landmark_pairs(&self, name: &str) -> Result<&Pairs, SceneError> {
        let k = self.landmark_measurement(name)?;
        match &self.run.prepared.measurements[k].data {
            MeasuredData::Landmarks { pairs, .. } => Ok(pairs),
            MeasuredData::Surface { .. } => unreachable!("a landmark measurement"),
        }
    }

    /// The index of the landmark measurement on node set `name`.
    fn landmark_measurement(&self, name: &str) -> Result<usize, SceneError> {
        self.measurement_of(MeasuredKind::Landmarks, name)
    }
}
