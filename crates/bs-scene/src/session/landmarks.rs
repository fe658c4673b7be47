//! New landmark pairs in a live session: a landmark `[[measurement]]`'s pairs replaced by
//! new ones (features tracked again in ultrasound) and fitted through the measurement's
//! boundary with the session's preparation (model, contact lists, preconditioner). The fit
//! starts from the reference state, as a cold run of a scene with those pairs does, so the
//! two agree (a landmark fit is several model solves from the reference anyway: its
//! Jacobian's).

use bs_dr::Progress;

use super::{MeasuredKind, Session};
use crate::SceneError;
use crate::measure::MeasuredData;
use crate::measure::pairs::Pairs;
use crate::run::Solved;
use crate::scene::LandmarkFiles;

impl Session {
    /// The node sets of the scene's landmark measurements: the keys
    /// [`Session::update_landmarks`] takes.
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
        let warm = std::mem::replace(&mut self.warm, false);
        match self.solve(observer) {
            Ok(solved) => Ok(solved),
            Err(e) => {
                self.warm = warm;
                self.run.prepared.measurements[k].data = previous;
                self.run.composed.fit = previous_fit;
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
