//! What a session remembers of its last two converged states for the next update's
//! predictor: the prescribed values of the last one, and the state before it with its
//! values (the reference state: zero displacements at zero values). When the new values
//! continue the last change along its line, and the two states have as many nodes in
//! contact (the response between them is one smooth branch), the update starts from the
//! secant predictor through them (`bs_dr::WarmStart::secant`), as a load continuation's
//! later levels do. Across a change of the contact set the secant extrapolates the wrong
//! branch: measured on the MNI152 updates at 4–8 mm it took 9–10 Newton iterations where
//! the linearised response takes 5–7, and settled one update 0.23 mm from the cold answer.
//! The count cannot see the update that *starts* contact (the two states before it are
//! both free): there bs-dr refuses a prediction that would more than double the contact
//! set and starts with a load step (`nk/loading.rs`, `predict`).

use bs_mesh::Vector3;

use crate::boundary::Prescribed;

/// How far the prescribed change of an update may leave the line of the last change
/// (relative to its own size) for the secant predictor to be used: the predictor then errs
/// inside the brain by about this share of the change (the prescribed nodes take their new
/// values exactly), less than the linearised response, which on the MNI152 demo leaves
/// about a third of a 1 mm change once the contact set moves.
pub const SECANT_DEVIATION: f64 = 0.2;

/// The last converged state's prescribed values and nodes in contact, and the state
/// before it with its values and nodes in contact.
#[derive(Debug, Clone)]
pub(crate) struct History {
    pub loads: Prescribed,
    pub contact: usize,
    pub before: Option<(Vec<Vector3<f64>>, Prescribed, usize)>,
}

impl History {
    /// At the reference state of a scene whose prescribed components are `pattern`.
    pub fn reference(pattern: &Prescribed) -> History {
        let loads = pattern.iter().map(|p| p.map(|v| v.map(|_| 0.0))).collect();
        History { loads, contact: 0, before: None }
    }

    /// The state before the last and the secant ratio for the new values `now` (see
    /// [`secant_ratio`]), when there is one and both states have as many nodes in contact.
    pub fn secant(&self, now: &Prescribed) -> Option<(&[Vector3<f64>], f64)> {
        let (before, values, contact) = self.before.as_ref()?;
        if *contact != self.contact {
            return None;
        }
        secant_ratio(values, &self.loads, now).map(|s| (before.as_slice(), s))
    }

    /// A state converged at `now` with `contact` nodes in contact: `last` (the previous
    /// state) becomes the one before.
    pub fn advance(&mut self, last: Vec<Vector3<f64>>, now: &Prescribed, contact: usize) {
        let values = std::mem::replace(&mut self.loads, now.clone());
        let last_contact = std::mem::replace(&mut self.contact, contact);
        self.before = Some((last, values, last_contact));
    }
}

/// The ratio `s` of the prescribed change `now − last` to `last − before` (over the
/// components prescribed in all three) when the first lies within [`SECANT_DEVIATION`] of
/// the line of the second and continues along it (`s > 0`); `None` otherwise, or when
/// either change is zero.
pub fn secant_ratio(before: &Prescribed, last: &Prescribed, now: &Prescribed) -> Option<f64> {
    let (mut pp, mut pn, mut nn) = (0.0, 0.0, 0.0);
    for ((b, l), n) in before.iter().zip(last).zip(now) {
        for c in 0..3 {
            if let (Some(b), Some(l), Some(n)) = (b[c], l[c], n[c]) {
                let (dp, dn) = (l - b, n - l);
                pp += dp * dp;
                pn += dp * dn;
                nn += dn * dn;
            }
        }
    }
    if !(pp > 0.0 && nn > 0.0) {
        return None;
    }
    let s = pn / pp;
    // |Δn − s Δp|² = |Δn|² − s ⟨Δp, Δn⟩.
    let off = (nn - s * pn).max(0.0);
    (s > 0.0 && off <= SECANT_DEVIATION * SECANT_DEVIATION * nn).then_some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn values(v: &[[f64; 3]]) -> Prescribed {
        v.iter().map(|x| x.map(Some)).collect()
    }

    #[test]
    fn the_ratio_follows_a_line_and_refuses_a_turn() {
        let before = values(&[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]);
        let last = values(&[[0.0, 0.0, -1.0], [0.0, 0.0, -2.0]]);
        // Twice the last change: s = 2 exactly.
        let on = values(&[[0.0, 0.0, -3.0], [0.0, 0.0, -6.0]]);
        assert_eq!(secant_ratio(&before, &last, &on), Some(2.0));
        // 10 % off the line (a perpendicular part of a tenth of the change): used, with
        // s the projection's ratio.
        let near = values(&[[0.1, 0.0, -2.0], [0.2, 0.0, -4.0]]);
        let s = secant_ratio(&before, &last, &near).unwrap();
        assert!((s - 1.0).abs() < 1e-12, "{s}");
        // At right angles, backwards, or no change: none.
        let turn = values(&[[1.0, 0.0, -1.0], [2.0, 0.0, -2.0]]);
        assert_eq!(secant_ratio(&before, &last, &turn), None);
        let back = values(&[[0.0, 0.0, -0.5], [0.0, 0.0, -1.0]]);
        assert_eq!(secant_ratio(&before, &last, &back), None);
        assert_eq!(secant_ratio(&before, &last, &last), None);
        assert_eq!(secant_ratio(&before, &before, &last), None);
    }

    #[test]
    fn a_change_of_the_contact_set_stops_the_secant() {
        let zero = values(&[[0.0; 3]]);
        let mut h = History::reference(&zero);
        h.advance(vec![Vector3::zeros()], &values(&[[0.0, 0.0, -1.0]]), 0);
        h.advance(vec![Vector3::new(0.0, 0.0, -1.0)], &values(&[[0.0, 0.0, -2.0]]), 0);
        assert_eq!(h.secant(&values(&[[0.0, 0.0, -3.0]])).map(|s| s.1), Some(1.0));
        h.advance(vec![Vector3::new(0.0, 0.0, -2.0)], &values(&[[0.0, 0.0, -3.0]]), 12);
        assert!(h.secant(&values(&[[0.0, 0.0, -4.0]])).is_none());
    }

    #[test]
    fn components_not_prescribed_are_left_out() {
        let mut before = values(&[[0.0; 3]]);
        let mut last = values(&[[0.0, 0.0, -1.0]]);
        let mut now = values(&[[5.0, 0.0, -2.0]]);
        for p in [&mut before, &mut last, &mut now] {
            p[0][0] = None;
        }
        assert_eq!(secant_ratio(&before, &last, &now), Some(1.0));
    }
}
