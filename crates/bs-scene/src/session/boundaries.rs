//! The session's prescribed boundaries by name: the resolved set of a node set (an error
//! listing the prescribed sets otherwise), and new values written into a copy of the
//! prescribed components (`sets.rs`).

use super::Session;
use super::sets::SetLoad;
use super::update::BoundaryValues;
use crate::SceneError;
use crate::boundary::Prescribed;

impl Session {
    /// The resolved boundary on node set `name`; an error listing the sets there are.
    pub(crate) fn set_load(&self, name: &str) -> Result<&SetLoad, SceneError> {
        self.sets.iter().find(|s| s.name == name).ok_or_else(|| {
            let known = self.prescribed_sets();
            SceneError::Set {
                scene: self.run.prepared.path.clone(),
                key: "update".into(),
                set: name.into(),
                message: format!(
                    "no [[boundary]] with this nset prescribes displacements; the scene's \
                     prescribed node sets are: {}",
                    if known.is_empty() { "none".into() } else { known.join(", ") }
                ),
            }
        })
    }

    /// The per-node prescribed values with `values` written for their sets (every other
    /// component keeps its last value).
    pub(crate) fn resolve(
        &self,
        values: &[(&str, &BoundaryValues)],
    ) -> Result<Prescribed, SceneError> {
        let p = &self.run.prepared;
        let mut prescribed = p.prescribed.clone();
        for (name, v) in values {
            self.set_load(name)?.write(p, v, &mut prescribed)?;
        }
        Ok(prescribed)
    }
}
