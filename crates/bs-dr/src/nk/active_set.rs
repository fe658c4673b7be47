//! The contact active set of the semismooth Newton iteration: which contact nodes are held,
//! on which surface feature, chosen every iteration from the trial points `x_a + γ_a r_a`
//! (the fixed-point form of the kinematic contact that Dynamic Relaxation iterates), and the
//! constraints and particular displacements that hold them.

use bs_mesh::{Point3, Vector3};

use super::outcome::NewtonKrylovError;
use crate::contact::{Contact, SurfaceFeature};
use crate::linalg::twolevel::{Constraints, Projector, TwoLevel};

/// The contact state of one node for one iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Active {
    Free,
    Held {
        target: Point3<f64>,
        feature: SurfaceFeature,
    },
    /// Held on the line where the planes of two faces meet: a node that alternated between
    /// the two faces, whose equilibrium is on their common edge. Each plane is a normal and
    /// a point of it.
    Crease {
        a: (Vector3<f64>, Point3<f64>),
        b: (Vector3<f64>, Point3<f64>),
    },
}

impl Active {
    /// Same state and feature (targets may differ).
    pub(crate) fn same_as(&self, other: &Active) -> bool {
        match (self, other) {
            (Active::Free, Active::Free) => true,
            (Active::Held { feature: a, .. }, Active::Held { feature: b, .. }) => match (a, b) {
                (SurfaceFeature::Face(n), SurfaceFeature::Face(m))
                | (SurfaceFeature::Edge(n), SurfaceFeature::Edge(m))
                | (
                    SurfaceFeature::Curved { normal: n, .. },
                    SurfaceFeature::Curved { normal: m, .. },
                ) => n.dot(m).abs() > 1.0 - 1e-6,
                (SurfaceFeature::Vertex, SurfaceFeature::Vertex) => true,
                _ => false,
            },
            (Active::Crease { a, b }, Active::Crease { a: c, b: d }) => {
                a.0.dot(&c.0) > 1.0 - 1e-6 && b.0.dot(&d.0) > 1.0 - 1e-6
            }
            _ => false,
        }
    }

    /// The crease of two faces a node alternated between: `previous` and `now` both held on
    /// faces with different normals (and not nearly opposite ones) that meet at a convex
    /// edge of the admissible region (each face's point inside the other's half-space: a
    /// node pressed into such an edge rests on it). At a reflex edge (a ridge into the
    /// cavity) the region is the union of the half-spaces and a node on the ridge slides off
    /// onto one face: no crease.
    pub(crate) fn crease(previous: &Active, now: &Active) -> Option<Active> {
        match (previous, now) {
            (
                Active::Held { target: r1, feature: SurfaceFeature::Face(n1) },
                Active::Held { target: r2, feature: SurfaceFeature::Face(n2) },
            ) if n1.dot(n2) < 1.0 - 1e-6
                && n1.dot(n2) > -0.5
                && n1.dot(&(r2 - r1)) <= 0.0
                && n2.dot(&(r1 - r2)) <= 0.0 =>
            {
                Some(Active::Crease { a: (*n1, *r1), b: (*n2, *r2) })
            }
            _ => None,
        }
    }

    /// Whether the out-of-balance force `push` (outward) at a crease node still presses on
    /// both planes: its components on the two normals are both non-negative.
    pub(crate) fn presses_on_both(&self, push: &Vector3<f64>) -> bool {
        let Active::Crease { a, b } = self else { return false };
        let (na, nb) = (a.0, b.0);
        let c = na.dot(&nb);
        let det = 1.0 - c * c;
        if det <= 1e-12 {
            return false;
        }
        let (pa, pb) = (na.dot(push), nb.dot(push));
        let mu_a = (pa - c * pb) / det;
        let mu_b = (pb - c * pa) / det;
        mu_a >= 0.0 && mu_b >= 0.0
    }

    /// Whether a crease is an edge of the surface: the point of its line closest to `x`
    /// lies on the surface (`closest(q)` is the surface point closest to `q`). The planes of
    /// two faces that do not share an edge near the node (a node far from equilibrium
    /// alternates between distant faces) meet on a line off the surface, and holding the node
    /// there would keep it off the surface.
    pub(crate) fn is_on_surface(
        &self,
        x: &Point3<f64>,
        mut closest: impl FnMut(&Point3<f64>) -> Option<Point3<f64>>,
    ) -> bool {
        let Active::Crease { a, b } = self else { return false };
        let q = self.crease_point(x);
        let scale = (q - x).norm() + (a.1 - b.1).norm();
        closest(&q).is_some_and(|p| (p - q).norm() <= 1e-6 * scale.max(f64::MIN_POSITIVE))
    }

    /// The point of a crease's line closest to `x` (the least-norm move onto both planes).
    fn crease_point(&self, x: &Point3<f64>) -> Point3<f64> {
        let Active::Crease { a: pa, b: pb } = self else { return *x };
        let (ga, gb) = (pa.0.dot(&(pa.1 - x)), pb.0.dot(&(pb.1 - x)));
        let c = pa.0.dot(&pb.0);
        let det = (1.0 - c * c).max(1e-12);
        x + pa.0 * ((ga - c * gb) / det) + pb.0 * ((gb - c * ga) / det)
    }
}

/// How the active set moved in one iteration.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct SetChange {
    /// Contact nodes whose state or feature changed.
    pub changes: usize,
    /// Of those, nodes back to their state of two iterations ago that are not on a crease
    /// (a cycle that damped steps break).
    pub cycling: usize,
}

/// The geometry a contact node's state is computed from.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NodeState<'a> {
    pub reference: &'a [Point3<f64>],
    pub u: &'a [Vector3<f64>],
    pub f: &'a [Vector3<f64>],
    /// The fixed components' projector.
    pub fixed: &'a Projector,
    /// Nodal compliances `γ_a`.
    pub gamma: &'a [f64],
}

/// The active set: the state of every contact node now and in the two iterations before.
#[derive(Debug, Clone)]
pub(crate) struct ActiveSet {
    pub active: Vec<Active>,
    previous: Vec<Active>,
    before_previous: Vec<Active>,
}

impl ActiveSet {
    /// Every one of `k` contact nodes free.
    pub(crate) fn new(k: usize) -> Self {
        ActiveSet {
            active: vec![Active::Free; k],
            previous: vec![Active::Free; k],
            before_previous: vec![Active::Free; k],
        }
    }

    /// Chooses every contact node's state from its trial point `x + γ r` and counts the
    /// changes against the last iteration.
    pub(crate) fn choose(
        &mut self,
        contact: &mut dyn Contact,
        nodes: &[usize],
        s: &NodeState<'_>,
    ) -> Result<SetChange, NewtonKrylovError> {
        let mut change = SetChange::default();
        for (k, &a) in nodes.iter().enumerate() {
            let x = s.reference[a] + s.u[a];
            let push = -(s.fixed.matrix[a] * s.f[a]);
            // A node on a crease stays there while the force presses it on both faces.
            if self.previous[k].presses_on_both(&push) {
                self.active[k] = self.previous[k];
                continue;
            }
            let y = x + push * s.gamma[a];
            let mut state = match contact.project(k, &y) {
                Some(proj) if proj.outside => {
                    Active::Held { target: proj.point, feature: proj.feature }
                }
                Some(_) => Active::Free,
                None => return Err(NewtonKrylovError::cannot_project()),
            };
            if !state.same_as(&self.previous[k]) {
                change.changes += 1;
                // Back to the feature of two iterations ago: the node alternates between two
                // faces, or between contact and freedom. Between two faces its equilibrium is
                // on their edge: hold it there. Otherwise full steps would repeat the cycle,
                // damped ones converge.
                if state.same_as(&self.before_previous[k]) {
                    let crease = Active::crease(&self.previous[k], &state).filter(|c| {
                        c.is_on_surface(&x, |q| contact.project(k, q).map(|p| p.point))
                    });
                    match crease {
                        Some(c) => state = c,
                        None => change.cycling += 1,
                    }
                }
            }
            self.active[k] = state;
        }
        Ok(change)
    }

    /// Holds every free node whose predicted position lies outside, at its projection
    /// (contact prediction of a load step). Returns how many were added.
    pub(crate) fn hold_predicted(
        &mut self,
        contact: &mut dyn Contact,
        nodes: &[usize],
        predicted: impl Fn(usize) -> Point3<f64>,
    ) -> usize {
        let mut added = 0;
        for (k, &a) in nodes.iter().enumerate() {
            if !matches!(self.active[k], Active::Free) {
                continue;
            }
            if let Some(proj) = contact.project(k, &predicted(a))
                && proj.outside
            {
                self.active[k] = Active::Held { target: proj.point, feature: proj.feature };
                added += 1;
            }
        }
        added
    }

    /// Warm start of a level from a predicted state: nodes held at the last level stay held,
    /// at the projection of their predicted position (moved onto the surface if they are
    /// off it); free nodes predicted outside are held at their projection. `position(a,
    /// Some(p))` moves node `a` to `p` and returns its position; `position(a, None)` returns
    /// its position. Nothing is counted as a change; returns the nodes newly held.
    pub(crate) fn keep(
        &mut self,
        contact: &mut dyn Contact,
        nodes: &[usize],
        mut position: impl FnMut(usize, Option<Point3<f64>>) -> Point3<f64>,
    ) -> usize {
        let mut added = 0;
        for (k, &a) in nodes.iter().enumerate() {
            let x = position(a, None);
            let Some(proj) = contact.project(k, &x) else { continue };
            let was_held = !matches!(self.active[k], Active::Free);
            if proj.outside || was_held {
                added += usize::from(!was_held);
                position(a, Some(proj.point));
                self.active[k] = Active::Held { target: proj.point, feature: proj.feature };
            } else {
                self.active[k] = Active::Free;
            }
        }
        self.previous.copy_from_slice(&self.active);
        self.before_previous.copy_from_slice(&self.active);
        added
    }

    /// Ends an iteration: the current states become the previous ones.
    pub(crate) fn settle(&mut self) {
        std::mem::swap(&mut self.before_previous, &mut self.previous);
        self.previous.copy_from_slice(&self.active);
    }

    /// Nodes held on the surface.
    pub(crate) fn held(&self) -> usize {
        self.active.iter().filter(|s| !matches!(s, Active::Free)).count()
    }

    /// Writes the constraints of the held nodes into `cons` (through the preconditioner,
    /// which keeps its block inverses in step), adds to `particular` the normal moves that
    /// put them on their features, and lists the tangential springs of curved features.
    pub(crate) fn constrain(
        &self,
        tl: &TwoLevel,
        cons: &mut Constraints,
        nodes: &[usize],
        s: &NodeState<'_>,
        particular: &mut [Vector3<f64>],
        springs: &mut Vec<(usize, f64)>,
    ) {
        let mut dirs = [Vector3::zeros(); 3];
        let mut held = [Vector3::zeros(); 3];
        springs.clear();
        for (k, &a) in nodes.iter().enumerate() {
            let x = s.reference[a] + s.u[a];
            let (target, m) = match self.active[k] {
                Active::Free => {
                    tl.constrain(cons, a, &[], &mut held);
                    continue;
                }
                crease @ Active::Crease { a: pa, b: pb } => {
                    let m = tl.constrain(cons, a, &[pa.0, pb.0], &mut held);
                    (crease.crease_point(&x), m)
                }
                Active::Held { target, feature } => {
                    if let SurfaceFeature::Curved { curvature, .. } = feature {
                        // The projection onto a surface of curvature κ from a trial point s
                        // beyond it shrinks tangential motions by 1/(1 + κs): in the
                        // linearised equilibrium, a tangential spring κ s / γ.
                        let y = x - s.fixed.matrix[a] * s.f[a] * s.gamma[a];
                        let dist = (y - target).norm();
                        springs.push((a, curvature * dist / s.gamma[a]));
                    }
                    let n = feature.constrained_directions(&mut dirs);
                    (target, tl.constrain(cons, a, &dirs[..n], &mut held))
                }
            };
            particular[a] +=
                held[..m].iter().fold(Vector3::zeros(), |acc, d| acc + d * d.dot(&(target - x)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn face(n: Vector3<f64>, p: Point3<f64>) -> Active {
        Active::Held { target: p, feature: SurfaceFeature::Face(n) }
    }

    #[test]
    fn two_faces_a_node_alternates_between_make_a_crease_whose_point_is_on_both_planes() {
        let n1 = Vector3::new(0.0, 0.0, 1.0);
        let n2 = Vector3::new(1.0, 0.0, 0.0);
        let (p1, p2) = (Point3::new(0.0, 0.0, 2.0), Point3::new(3.0, 0.0, 0.0));
        let c = Active::crease(&face(n1, p1), &face(n2, p2)).expect("a crease");
        let q = c.crease_point(&Point3::new(1.0, 5.0, 1.0));
        assert!((q - Point3::new(3.0, 5.0, 2.0)).norm() < 1e-12, "{q}");
        // On the surface when the closest surface point of the crease point is itself; a
        // line of two distant faces' planes is not.
        assert!(c.is_on_surface(&Point3::new(2.5, 0.0, 1.5), |q| Some(*q)));
        assert!(!c.is_on_surface(&Point3::new(2.5, 0.0, 1.5), |q| Some(q + Vector3::x())));
        // A reflex edge (each face point outside the other's plane) makes no crease.
        let (q1, q2) = (Point3::new(5.0, 0.0, 2.0), Point3::new(3.0, 0.0, 4.0));
        assert!(Active::crease(&face(n1, q1), &face(n2, q2)).is_none());
        // Opposite faces (a thin wall) make no crease.
        assert!(Active::crease(&face(n1, p1), &face(-n1, p2)).is_none());
    }

    #[test]
    fn a_crease_holds_while_the_force_presses_on_both_planes() {
        let n1 = Vector3::new(0.0, 0.0, 1.0);
        let n2 = Vector3::new(1.0, 0.0, 0.0);
        let c = Active::Crease { a: (n1, Point3::origin()), b: (n2, Point3::origin()) };
        assert!(c.presses_on_both(&Vector3::new(1.0, 0.0, 1.0)));
        assert!(!c.presses_on_both(&Vector3::new(-1.0, 0.0, 1.0)));
        assert!(!Active::Free.presses_on_both(&Vector3::new(1.0, 1.0, 1.0)));
    }

    #[test]
    fn faces_with_the_same_normal_are_the_same_state_whatever_the_target() {
        let n = Vector3::new(0.0, 1.0, 0.0);
        assert!(face(n, Point3::origin()).same_as(&face(n, Point3::new(1.0, 2.0, 3.0))));
        assert!(!face(n, Point3::origin()).same_as(&Active::Free));
        let e = Active::Held { target: Point3::origin(), feature: SurfaceFeature::Edge(n) };
        assert!(!face(n, Point3::origin()).same_as(&e));
    }
}
