//! Which element inverted: after a force evaluation flagged one, the lowest-indexed element
//! (mesh order) whose `J` (or T4ANP `J̄`) is not positive and finite, so the report does not
//! depend on the thread count.

use crate::element::TetFormulation;

use super::elements::Elements;

/// An element found inverted (`J ≤ 0` or non-finite) while computing forces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inversion {
    /// Element index (mesh order).
    pub element: usize,
    /// External element id.
    pub element_id: u64,
    /// Its `det F`.
    pub jacobian: f64,
}

impl Elements {
    /// The lowest-indexed element (mesh order) whose `J` (or, for T4ANP tets with a valid
    /// `J`, whose `J̄`) is not > 0 and finite. `tjac(t)` is the `J` of tet `t`.
    pub(crate) fn first_inversion(
        &self,
        tjac: impl Fn(usize) -> f64,
        hjac: &[f64],
        jnodal: &[f64],
    ) -> Inversion {
        let mut best: Option<Inversion> = None;
        let mut consider = |e: usize, jj: f64| {
            if !(jj > 0.0 && jj.is_finite()) && best.is_none_or(|b| e < b.element) {
                best =
                    Some(Inversion { element: e, element_id: self.element_ids[e], jacobian: jj });
            }
        };
        for (k, t) in self.tets.iter().enumerate() {
            let j = tjac(k);
            let jbar = if self.tet == TetFormulation::T4Anp {
                0.25 * t.anp.iter().map(|&g| jnodal[g as usize]).sum::<f64>()
            } else {
                j
            };
            consider(self.tet_element(k), if j > 0.0 && j.is_finite() { jbar } else { j });
        }
        for (k, &j) in hjac.iter().enumerate() {
            consider(self.hex_element(k), j);
        }
        best.unwrap_or(Inversion {
            element: 0,
            element_id: self.element_ids[0],
            jacobian: f64::NAN,
        })
    }
}
