//! The coarse levels of a contact set: the Galerkin levels of `(Π P)ᵀ K (Π P)` for the
//! constraints of a solve (the fixed components and the contact normals of held nodes),
//! built on the setup's patterns and symbolic factor (only the held nodes' rows of `P`
//! change, `Π_a P_a`).
//!
//! The setup's coarse levels know only the fixed components: with nodes held on the skull
//! their correction is not the Galerkin one of the constrained operator, and GMRES needs
//! more iterations (the MNI152 demo's warm updates at 4–8 mm: 189 against 246 GMRES
//! iterations; its cold solve 78 → 51).

use rayon::prelude::*;
use std::sync::Arc;

use super::constraints::{Built, Constraints};
use super::levels::Levels;
use super::params::MultilevelError;
use super::projector::Projector;
use super::setup::Multilevel;
use crate::linalg::nodal::NodalMatrix;

/// [`Multilevel::constrain_coarse`] builds coarse levels for the first constraints that
/// hold nodes and rebuilds them only when more nodes changed their constraints since than
/// are held (a contact set that turned over). Measured on the MNI152 demo's `cargo xtask
/// bench update` (warm updates at 4–8 mm, GMRES iterations, coarse builds over the 16 solves
/// of the bench): rebuilt at 10 % changed 194 GMRES / 36 builds, at 30 % 181 / 36, this rule
/// 177 / 19; without it 246.
const STALE_FRACTION: f64 = 1.0;

/// Fewer changed nodes than this never build: a few held nodes barely change the coarse
/// problem, and a build costs about as much as five GMRES iterations (the bench: 181 GMRES
/// and 18 builds against 177 and 19 with a minimum of 8).
const STALE_MIN: usize = 50;

impl Multilevel {
    /// The coarse levels of the operator `k` under the constraints `pi`, and the number of
    /// nodes `pi` holds beyond `fixed`.
    pub(super) fn levels_under(
        &self,
        k: &NodalMatrix,
        fixed: &Projector,
        pi: &Projector,
    ) -> Result<Built, MultilevelError> {
        let st = &self.structure;
        let held = |a: usize| pi.constrained[a] && pi.matrix[a] != fixed.matrix[a];
        let count = (0..pi.matrix.len()).into_par_iter().filter(|&a| held(a)).count();
        let products = if count == 0 {
            st.fine.galerkin_fine(k, &st.p, &st.pt)
        } else {
            let mut p = st.p.clone();
            p.rows_mut().into_par_iter().enumerate().with_min_len(1024).for_each(|(a, row)| {
                if held(a) {
                    row.iter_mut().for_each(|b| *b = pi.matrix[a] * *b);
                }
            });
            let mut pt = st.pt.clone();
            p.transpose_into(&st.pt_source, &mut pt);
            st.fine.galerkin_fine(k, &p, &pt)
        };
        let levels: Levels = st.coarse.levels(products.a1.clone())?;
        let fine = self.retained.is_some().then(|| Arc::new(products));
        Ok(Built {
            levels: Arc::new(levels),
            fine,
            projector: Arc::new(pi.matrix.clone()),
            held: count,
        })
    }

    /// Keeps in `con` the coarse levels of `(Π P)ᵀ K (Π P)` for its constraints, when the
    /// operator was kept ([`MultilevelParams::contact_coarse`](super::MultilevelParams)):
    /// built once at least [`STALE_MIN`] nodes are constrained otherwise than the levels in
    /// use were built for, and, when those held nodes too, once more nodes changed than are
    /// held ([`STALE_FRACTION`]); back to the preconditioner's own when no node is held
    /// and its own hold none. Returns whether it built levels.
    pub fn constrain_coarse(&self, con: &mut Constraints) -> bool {
        let Some(k) = &self.retained else { return false };
        let (pi, fixed) = (&con.projector, &self.fixed.projector);
        let reference = con.levels.as_ref().unwrap_or(&self.levels);
        let n = pi.matrix.len();
        let held = |a: usize| pi.constrained[a] && pi.matrix[a] != fixed.matrix[a];
        let (held_count, stale) = (0..n)
            .into_par_iter()
            .with_min_len(1024)
            .map(|a| (usize::from(held(a)), usize::from(pi.matrix[a] != reference.projector[a])))
            .reduce(|| (0, 0), |x, y| (x.0 + y.0, x.1 + y.1));
        if held_count == 0 && self.levels.held == 0 {
            con.levels = None;
            return false;
        }
        let turned = (stale as f64) > STALE_FRACTION * held_count as f64;
        if stale < STALE_MIN || (reference.held > 0 && !turned) {
            return false;
        }
        // A correction of the preconditioner's own levels where it kept their products;
        // a failed factor keeps the levels in use, and is not tried again for these
        // constraints.
        let built = match &self.levels.fine {
            Some(products) => self.corrected(k, products, pi),
            None => self.levels_under(k, fixed, pi),
        };
        let ok = built.is_ok();
        con.levels = Some(built.unwrap_or_else(|_| Built {
            levels: reference.levels.clone(),
            fine: None,
            projector: Arc::new(pi.matrix.clone()),
            held: held_count,
        }));
        ok
    }
}
