//! Resection during a live session: a region's elements leave the model (see
//! [`crate::resection`]), the session's preparation is redone on what remains (the model,
//! the contact's slave nodes, the solver's preconditioner), and the brain is solved again
//! warm from its last good state with the boundaries' current values.

use bs_dr::Progress;

use super::Session;
use super::history::History;
use crate::SceneError;
use crate::prepare::Prepared;
use crate::run::{Run, Solved};

impl Session {
    /// The element sets of the scene's regions not resected yet (what [`Session::resect`]
    /// takes).
    pub fn regions(&self) -> Vec<&str> {
        let p = &self.run.prepared;
        p.scene.regions.iter().filter(|r| !r.resected).map(|r| r.elset.as_str()).collect()
    }

    /// Resects the region whose element set is `region` and solves warm from the last good
    /// state. On any error (no such region, a resection that would remove everything or
    /// leave a part unheld, a solve that fails) the session keeps its model and state.
    pub fn resect(
        &mut self,
        region: &str,
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solved, SceneError> {
        let prepared = self.resected(region)?;
        let run = Run::prepare(prepared)?;
        let sets = super::sets::resolve_sets(&run.prepared)?;
        let old_sets = std::mem::replace(&mut self.sets, sets);
        let old_fit = self.boundary_fit.take();
        let old_run = std::mem::replace(&mut self.run, run);
        let old_pattern = self.scene_prescribed.clone();
        crate::resection::hold_unused(&self.run.prepared.mesh, &mut self.scene_prescribed);
        let old_history =
            std::mem::replace(&mut self.history, History::reference(&self.scene_prescribed));
        self.solve(observer).inspect_err(|_| {
            self.sets = old_sets;
            self.boundary_fit = old_fit;
            self.run = old_run;
            self.scene_prescribed = old_pattern;
            self.history = old_history;
        })
    }

    /// The session's scene with `region` resected, prepared on its current mesh with the
    /// boundaries' current values (earlier resections' cavity walls kept).
    fn resected(&self, region: &str) -> Result<Prepared, SceneError> {
        let p = &self.run.prepared;
        let Some(r) = p.scene.regions.iter().position(|r| r.elset == region && !r.resected) else {
            return Err(SceneError::Set {
                scene: p.path.clone(),
                key: "resect".into(),
                set: region.into(),
                message: format!(
                    "not a region of the scene still in the model; the regions are: {}",
                    self.regions().join(", ")
                ),
            });
        };
        let mut scene = p.scene.clone();
        scene.regions[r].resected = true;
        let mut next = Prepared::from_parts(&p.path, scene, p.mesh.clone(), p.skull.clone())?;
        let mut prescribed = p.prescribed.clone();
        crate::resection::hold_unused(&next.mesh, &mut prescribed);
        next.prescribed = prescribed;
        if let (Some(new), Some(old)) = (&mut next.resection, &p.resection) {
            new.regions.splice(0..0, old.regions.iter().cloned());
            new.elements += old.elements;
            new.walls.extend(old.walls.iter().cloned());
        }
        Ok(next)
    }
}
