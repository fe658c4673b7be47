//! σ of a session's fitted answer (`serve --uncertainty`): the run's sampling
//! ([`crate::uncertainty::sample`]) on the composition the last update left.

use super::Session;
use crate::SceneError;
use crate::run::Solved;
use crate::uncertainty::{Uncertainty, UncertaintyParams};

impl Session {
    /// σ of `solved`, the answer of the session's last update: as `run --uncertainty`
    /// samples it, through the tangent at that answer with the data the update fitted.
    pub fn uncertainty(
        &mut self,
        solved: &Solved,
        params: &UncertaintyParams,
    ) -> Result<Uncertainty, SceneError> {
        crate::uncertainty::sample(&mut self.run, solved, params)
    }
}
