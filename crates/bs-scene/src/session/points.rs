//! New scans in a live session: a `[[measurement]]`'s point cloud replaced by a new scan of
//! the same patch and fitted, with the session's preparation (model, contact lists,
//! preconditioner) reused. The fit starts from the reference state, as a cold run does: a
//! warm start from the last fit lands elsewhere within the scan planes' refresh
//! hysteresis (0.78 mm on fixtures/fit) and, at full strength from its first iteration,
//! can cycle between planes (docs/decisions.md). The scan's rigid correction is the one
//! estimated from the scene's bone points (the navigation's registration does not change
//! between scans); its data stiffness follows the area the new scan covers.

use bs_dr::{DataTerm, Progress, Springs};
use bs_fit::Term;
use bs_mesh::Point3;

use super::{MeasuredKind, Session};
use crate::SceneError;
use crate::measure::MeasuredData;
use crate::run::Solved;

impl Session {
    /// The node sets of the scene's scanned-surface measurements: the keys
    /// [`Session::update_points`] takes.
    pub fn measured_sets(&self) -> Vec<&str> {
        self.sets_of(MeasuredKind::Surface)
    }

    /// Replaces the scans of the measurements on the named node sets by `scans` (scene frame
    /// and units, before the rigid correction) and fits them from the reference state (see
    /// the module documentation). On any error the session keeps its last good state and
    /// scans.
    pub fn update_points(
        &mut self,
        scans: &[(String, Vec<Point3<f64>>)],
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solved, SceneError> {
        let mut previous = Vec::new();
        for (name, points) in scans {
            let k = self.measurement(name)?;
            self.check_scan(k, name, points)?;
            previous.push((k, self.replace_scan(k, points.clone())));
        }
        let warm = std::mem::replace(&mut self.warm, false);
        match self.solve(observer) {
            Ok(solved) => Ok(solved),
            Err(e) => {
                self.warm = warm;
                for (k, points) in previous.into_iter().rev() {
                    self.replace_scan(k, points);
                }
                Err(e)
            }
        }
    }

    /// The index of the scanned-surface measurement on node set `name`.
    fn measurement(&self, name: &str) -> Result<usize, SceneError> {
        self.measurement_of(MeasuredKind::Surface, name)
    }

    /// Refuses an empty scan, a non-finite point, and a scan in another frame or unit.
    fn check_scan(&self, k: usize, name: &str, points: &[Point3<f64>]) -> Result<(), SceneError> {
        let p = &self.run.prepared;
        let key = format!("update points[\"{name}\"]");
        let err =
            |message: String| SceneError::Read { scene: p.path.clone(), key: key.clone(), message };
        if points.is_empty() {
            return Err(err("the scan has no points".into()));
        }
        if let Some(i) = points.iter().position(|q| !q.iter().all(|x| x.is_finite())) {
            return Err(err(format!("point {i} has a non-finite coordinate")));
        }
        let m = &p.measurements[k];
        let MeasuredData::Surface { faces, .. } = &m.data else { unreachable!("a surface") };
        let file = std::path::Path::new("the scan");
        crate::measure::read::check_frame(
            &p.path,
            &p.scene,
            &p.mesh,
            &key,
            file,
            points,
            faces,
            m.max_distance,
        )
    }

    /// Puts `points` (as measured) in measurement `k`'s place, corrected by its rigid fit,
    /// with the data stiffness of the area they cover; returns the points it replaces.
    fn replace_scan(&mut self, k: usize, points: Vec<Point3<f64>>) -> Vec<Point3<f64>> {
        let run = &mut self.run;
        let mu = match &run.prepared.measurements[k].data {
            MeasuredData::Surface { face_elements, .. } => face_elements
                .iter()
                .map(|&e| crate::measure::terms::shear_modulus(&run.prepared, e))
                .fold(0.0f64, f64::max),
            MeasuredData::Landmarks { .. } => unreachable!("a surface measurement"),
        };
        let MeasuredData::Surface { points: kept, .. } = &mut run.prepared.measurements[k].data
        else {
            unreachable!("a surface measurement")
        };
        let old = std::mem::replace(kept, points.clone());
        let sigma = run.prepared.measurements[k].sigma;
        let state = run.composed.fit.as_mut().expect("a scene with measurements has a fit");
        let corrected: Vec<Point3<f64>> = match &state.rigid[k] {
            Some(f) => points.iter().map(|q| f.rigid.apply(q)).collect(),
            None => points,
        };
        let Term::Surface(term) = &mut state.fits.terms[k] else { unreachable!("a surface") };
        term.set_points(corrected);
        let reference = &run.prepared.mesh.nodes;
        term.linearise(reference, &mut Springs::new());
        let area = term.covered_area();
        let kappa = bs_fit::surface_stiffness(mu, sigma, area, term.mean_edge());
        term.set_stiffness(kappa);
        state.stiffness[k] = kappa;
        state.covered_area[k] = area;
        old
    }
}
