//! The contact active set of the semismooth Newton iteration: which contact nodes are held,
//! on which surface feature, chosen every iteration from the trial points `x_a + γ_a r_a`
//! (the fixed-point form of the kinematic contact that Dynamic Relaxation iterates), and the
//! constraints and particular displacements that hold them.
//!
//! A faceted skull has pockets: seen from inside, every convex edge and vertex of the cavity
//! is a place a pressed node slides into and stays, held in two or three directions. The
//! trial point of a node near a pocket lands on one of the faces around it, and which one
//! turns on small tangential forces: on the paper's 40 mm ellipsoid, tens of nodes a
//! iteration moved from face to edge to face near the cavity's vertices, the line search
//! fell to 1/16 and the level stalled — or converged, when rounding went the other way (the
//! verdict flipped with Young's modulus changed in the 12th digit). A node held on a face
//! therefore also looks [`POCKET_DEPTH`] times deeper along the face normal: where that
//! deeper point projects onto a sharper feature (an edge or a vertex) close to the first
//! projection, the node is held there.

use bs_mesh::{Point3, Vector3};

use super::outcome::NewtonKrylovError;
use crate::contact::{Contact, SurfaceFeature};
use crate::linalg::multilevel::{Constraints, Multilevel, Projector};

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

/// How much deeper than its trial point a node held on a face looks for a pocket: the
/// normal part of the trial step is taken this many times (see the module documentation).
/// On the 40 mm ellipsoid (coarse, six perturbations of Young's modulus) depths 2, 3 and 5
/// all converged every time (54–69 iterations) where 1 (no look) converged three times in
/// six; on the MNI152 brain 3 was the best of the three at 16 and 25 mm.
pub(crate) const POCKET_DEPTH: f64 = 3.0;

/// The state a trial point `y` gives contact node `k`: held at its projection when it lies
/// outside, free otherwise.
fn held_at(
    contact: &mut dyn Contact,
    k: usize,
    y: &Point3<f64>,
) -> Result<Active, NewtonKrylovError> {
    match contact.project(k, y) {
        Some(proj) if proj.outside => {
            Ok(Active::Held { target: proj.point, feature: proj.feature })
        }
        Some(_) => Ok(Active::Free),
        None => Err(NewtonKrylovError::cannot_project()),
    }
}

/// The state of a node near a pocket: `deeper` (the state of the deeper trial point) when it
/// holds the node on a sharper feature than `state` whose point is within `reach` (the
/// distance between the two trial points) of `state`'s; `state` otherwise. The projection
/// onto a convex region moves no farther than its argument, so a point farther away belongs
/// to another part of the surface (a fold of a real skull), not to the pocket.
fn pocket(state: Active, deeper: Active, reach: f64) -> Active {
    match (state, deeper) {
        (Active::Held { target: t, feature: f }, Active::Held { target: d, feature: g })
            if sharpness(&g) > sharpness(&f) && (d - t).norm() <= reach =>
        {
            deeper
        }
        _ => state,
    }
}

/// How many directions a feature holds: a face (flat or curved) one, an edge two, a vertex
/// three.
fn sharpness(f: &SurfaceFeature) -> usize {
    match f {
        SurfaceFeature::Face(_) | SurfaceFeature::Curved { .. } => 1,
        SurfaceFeature::Edge(_) => 2,
        SurfaceFeature::Vertex => 3,
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
            let mut state = held_at(contact, k, &y)?;
            if let Active::Held { feature: SurfaceFeature::Face(n), .. } = self.previous[k] {
                let deeper = y + n * (n.dot(&push) * s.gamma[a] * (POCKET_DEPTH - 1.0));
                state = pocket(state, held_at(contact, k, &deeper)?, (deeper - y).norm());
            }
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
        tl: &Multilevel,
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
    fn a_deeper_trial_point_holds_a_node_in_a_nearby_pocket_only() {
        let n = Vector3::new(0.0, 0.0, 1.0);
        let on_face = face(n, Point3::new(1.0, 0.0, 0.0));
        let t = Vector3::new(1.0, 0.0, 0.0);
        let edge = |x: f64| Active::Held {
            target: Point3::new(x, 0.0, 0.0),
            feature: SurfaceFeature::Edge(t),
        };
        let vertex =
            Active::Held { target: Point3::new(1.2, 0.0, 0.0), feature: SurfaceFeature::Vertex };
        // An edge or a vertex within reach: the pocket.
        assert_eq!(pocket(on_face, edge(1.3), 0.5), edge(1.3));
        assert_eq!(pocket(on_face, vertex, 0.5), vertex);
        assert_eq!(pocket(edge(1.1), vertex, 0.5), vertex);
        // Farther than the trial points are apart: another part of the surface.
        assert_eq!(pocket(on_face, edge(2.0), 0.5), on_face);
        // Not sharper (a face, or an edge seen from a vertex), or either point free.
        assert_eq!(pocket(on_face, face(n, Point3::new(1.1, 0.0, 0.0)), 0.5), on_face);
        assert_eq!(pocket(vertex, edge(1.2), 0.5), vertex);
        assert_eq!(pocket(Active::Free, vertex, 5.0), Active::Free);
        assert_eq!(pocket(on_face, Active::Free, 5.0), on_face);
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
