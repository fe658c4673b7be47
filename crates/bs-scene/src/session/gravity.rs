//! Gravity turned in a live session: the head is repositioned during surgery, and the
//! scene's `[gravity]` direction with it. The body force's nodal loads are integrated again
//! on the session's model (the fluid's level stays where the scene put it) and the next solve
//! starts warm from the last good state with the new loads in full.

use bs_dr::Progress;

use super::Session;
use crate::SceneError;
use crate::compose::loads_of;
use crate::run::Solved;

impl Session {
    /// The direction of the scene's gravity now (`None`: the scene has no `[gravity]`).
    pub fn gravity_direction(&self) -> Option<[f64; 3]> {
        self.run.prepared.scene.gravity.as_ref().map(|g| g.direction)
    }

    /// Makes `direction` (scene frame, any length but zero) gravity's direction for the next
    /// solves; returns the one it replaces. Refused for a scene without `[gravity]` and for
    /// a zero or non-finite direction; nothing changes then.
    pub fn set_gravity(&mut self, direction: [f64; 3]) -> Result<[f64; 3], SceneError> {
        let p = &self.run.prepared;
        let err = |message: String| SceneError::Scene { file: p.path.clone(), message };
        let Some(g) = &p.scene.gravity else {
            return Err(err("the scene has no [gravity] to turn: add a [gravity] table (and \
                            material densities) to the scene"
                .into()));
        };
        let mut turned = g.clone();
        turned.direction = direction;
        turned.validate().map_err(err)?;
        let body = crate::compose::dead_loads(p, &self.run.composed.model, Some(&turned))?;
        let loads = loads_of(p, &p.prescribed, &body)?;
        let c = &mut self.run.composed;
        c.body = body;
        c.loads = loads;
        let scene_gravity = self.run.prepared.scene.gravity.as_mut().expect("checked above");
        Ok(std::mem::replace(&mut scene_gravity.direction, direction))
    }

    /// Turns gravity to `direction` and solves warm from the last good state; on any error
    /// the session keeps its last good state and direction.
    pub fn update_gravity(
        &mut self,
        direction: [f64; 3],
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solved, SceneError> {
        let previous = self.set_gravity(direction)?;
        self.solve(observer).inspect_err(|_| {
            self.set_gravity(previous).expect("the previous direction was accepted before");
        })
    }
}
