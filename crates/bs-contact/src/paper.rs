//! The paper's algorithm (Joldes et al., brain–skull contact, section 3): bucket search for
//! the closest master node C, local search over the faces and edges around C and the
//! precomputed per-node lists of additional edges and faces (§3.2), the eq. (1) skip, the
//! `RP · n` penetration test.
//!
//! # How we read §3.2
//!
//! *Edges.* "In triangle ABC, the location of nodes that are closer to C than to A and B (R)
//! is delimited by the lines OP and ON … If [CM] < [AM] or ([CM] > [AM] and [OM] < d) then AB
//! is added." We take **M = the midpoint of AB**. Reason: a point X of segment AB is closer
//! to C than to both A and B iff C lies in the ball centred at X with radius
//! min(|XA|, |XB|); every such ball is inside the ball with diameter AB (centre M, radius
//! |AM|), and the ball centred at M is one of them. So "AB crosses R" ⇔ |CM| < |AM|, which is
//! the first condition read with M the midpoint. O is the circumcentre of triangle ABC, so
//! M is also the foot of O on AB and [OM] is the distance from the apex line of the wedge R
//! to AB: the second condition is meant to say "AB passes within d of R" (the paper:
//! "equivalent to the edge AB crossing or being very close (less than d) to R"). But [OM] is
//! that distance only when ABC is acute at A and B; when it is obtuse at A or B, R reaches
//! closer to AB than O, and the printed test misses edges that are the closest feature of
//! an outside slave within d (found by our brute-force comparison on ellipsoids and convex
//! polyhedra). We therefore implement the stated intent, with a conservative lower bound of
//! the distance from AB to R ([`edge_needs_check`]); it accepts every edge the printed test
//! accepts. The printed test is kept as [`edge_needs_check_literal`] behind
//! [`PaperParams::literal_list_tests`], with a regression test showing its miss. When A, B, C
//! are collinear the circumcircle is at infinity and the printed second condition is false.
//! (The equality case |CM| = |AM| has O = M, so [OM] = 0 < d: both readings add it.)
//!
//! *Faces.* "R" in "[CR] > 2·[T₁R]" is the projection of the circumsphere centre O of
//! tetrahedron C T₁T₂T₃ on the face, i.e. **the circumcentre of T₁T₂T₃**, and [T₁R] is the
//! face's circumradius ρ. The discard is sound for points of the face: a point X of the
//! triangle is within ρ of its nearest vertex and |XC| ≥ |CR| − ρ > ρ. The normal n is the
//! face normal **oriented towards C's side of the face plane** ("pointing in the direction of
//! C"); when C lies in the plane we take the outward normal. D_i = T_i + d·n, E_i the
//! midpoints of D₁D₂D₃'s sides, O₁ its circumcentre, included only if it lies inside the
//! (closed) triangle D₁D₂D₃. The face is added if some S satisfies M_iS · M_iC > 0 for
//! i = 1, 2, 3 (eq. 2), M_i the midpoint of CT_i. That is [`face_needs_check_literal`].
//!
//! Its purpose, in the paper's words, is to find "all the faces … that are possible to be
//! penetrated by a slave node P in the case C is the closest master node". Two steps fall
//! short of it: the discard `[CR] > 2ρ` is proven only for points *on* the face (a point
//! lifted by s ≤ d off the face can be closer to C), and the seven sample points can all
//! miss R while R still meets the layer within d of the face. The brute-force comparison
//! finds such misses (mostly slaves inside the cavity, within d, with C behind the face
//! plane; also an outside one on a bumpy surface with d = 2 edges). We implement the purpose
//! ([`face_needs_check`]): the discard with √(ρ² + d²) in place of ρ, then an exact
//! feasibility test of "some point within d of the face interior, on either side, is closer
//! to C than to T₁, T₂, T₃" (a 3-variable linear program solved by vertex enumeration).
//! The printed test comes back with [`PaperParams::literal_list_tests`].
//!
//! *Which edges and faces are examined.* "Any edge AB that does not contain C and is not part
//! of the same master triangle as C". Read literally, the edge AB opposite C in a face CAB is
//! never examined, and the basic tests do not look at it either (they test the faces at C,
//! the edges *containing* C and C). When CAB is obtuse at C, R crosses AB and a slave
//! outside the dihedral of AB, closest to C among the nodes, has its closest point on AB:
//! the brute-force comparison finds such misses on every test surface. We examine every edge
//! not containing C (the opposite edges included); the printed exclusion comes back with
//! [`PaperParams::literal_list_tests`]. Faces containing C are skipped. Candidates come from
//! bucket grids as §3.2 says: edges by midpoint (bucket size half the longest edge on every
//! axis), faces by circumcentre (bucket size the largest circumradius). An edge within d of R
//! has |CM| ≤ L_max + 2d (a point Y of R within d of X on AB has |YC| ≤ min(|YA|, |YB|) ≤
//! d + L/2), so only midpoints within L_max + 2d of C are examined; the face discard leaves
//! only circumcentres within 2·√(ρ_max² + d²) of C (2·ρ_max for the printed test). These
//! radii lose nothing the tests would accept.
//!
//! *Eq. (1).* `CP² > d² + r²` skips the basic tests (faces, edges around C and C itself).
//! It is sound: if the closest point X of P on a face or edge containing C were within d of
//! P, then P − X is perpendicular to a plane or line through X and C, so
//! |CP|² = |PX|² + |XC|² ≤ d² + r².
//!
//! *Closest node.* The paper searches P's bucket and its 26 neighbours; that block does not
//! always contain the closest node (P in the middle of a large triangle, P deep inside or
//! far outside). We search those 27 first, then certify: if every unvisited bucket is
//! farther than the node C found, done; else scan C's precomputed sorted neighbourhood up to
//! 2|CP| (every closer node is there); an empty block starts from a per-bucket seed node;
//! only when the neighbourhood does not reach 2|CP| does the bucket search widen. So C is
//! always the exact closest master node (ties: smallest index), also for P outside the
//! grid (its bucket index is clamped). Unused vertices are not in the grid.
//!
//! *Local search.* Faces around C pass the bisector filter `CP · b > 0` and are kept when
//! the projection of P on the face plane lies inside the closed triangle; edges around C
//! when the projection on the edge line lies inside the closed segment; then C itself; then
//! the additional edges and faces with the same projection tests. The nearest candidate wins
//! (first offered on exact ties). The verdict is `RP · n > 0` ⇒ outside (n outward here; the paper's
//! inside normal with the opposite sign).

use std::sync::Arc;

use bs_mesh::TriSurface;
use nalgebra::{Point3, Vector3};

use crate::ContactError;
use crate::geometry::{circumcentre, project_inside_triangle};
use crate::grid::BucketGrid;
use crate::master::MasterSurface;
use crate::query::Feature;
use crate::query::{ClosestPoint, Projection};

/// Parameters of the paper's preprocessing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperParams {
    /// d, the largest penetration possible in one step (model length unit). `None` (the
    /// default) takes a quarter of the longest master edge: in Dynamic Relaxation a node
    /// moves a small fraction of the smallest element per step (the stable step bounds it),
    /// and a slave that was corrected at the previous step starts on the skull, so one
    /// step's penetration is one step's displacement; a quarter skull edge is far above that
    /// for meshes of comparable resolution. A larger d makes the additional lists longer
    /// (slower local search); the solver can pass its own bound.
    pub max_step_penetration: Option<f64>,
    /// Whether to build and search the §3.2 additional lists (on by default; off only to
    /// show what goes wrong without them).
    pub additional_lists: bool,
    /// Use the §3.2 list rules exactly as printed (off by default): for edges, skip edges of
    /// triangles that contain C and test `[OM] < d` ([`edge_needs_check_literal`]); for
    /// faces, the circumsphere discard and the seven sample points
    /// ([`face_needs_check_literal`]). The printed rules miss closest features that the
    /// rules as the paper states their purpose find ([`edge_needs_check`],
    /// [`face_needs_check`]); the regression tests show both.
    pub literal_list_tests: bool,
}

impl Default for PaperParams {
    fn default() -> Self {
        Self { max_step_penetration: None, additional_lists: true, literal_list_tests: false }
    }
}

/// The per-node lists of additional edges and faces (§3.2), CSR.
#[derive(Debug, Clone, Default)]
pub struct AdditionalLists {
    /// Offsets into `edges` per node.
    pub edge_start: Vec<u32>,
    /// Additional edges.
    pub edges: Vec<u32>,
    /// Offsets into `faces` per node.
    pub face_start: Vec<u32>,
    /// Additional faces.
    pub faces: Vec<u32>,
}

impl AdditionalLists {
    /// Additional edges of node `c`.
    #[inline]
    pub fn edges_of(&self, c: u32) -> &[u32] {
        &self.edges[self.edge_start[c as usize] as usize..self.edge_start[c as usize + 1] as usize]
    }

    /// Additional faces of node `c`.
    #[inline]
    pub fn faces_of(&self, c: u32) -> &[u32] {
        &self.faces[self.face_start[c as usize] as usize..self.face_start[c as usize + 1] as usize]
    }
}

/// §3.2 edge test for node C and edge AB, as printed: M = midpoint of AB, O = circumcentre of
/// ABC; add if `[CM] < [AM]` or `[OM] < d`.
///
/// `[OM]` is the distance from AB to the region R (points closer to C than to A and B) only
/// when the angles of ABC at A and B are acute; otherwise R comes closer to AB than O does
/// and this test misses edges that a slave within d can have as closest feature (see
/// [`edge_needs_check`] and the regression test `literal_list_rules_miss_closest_features`).
pub fn edge_needs_check_literal(c: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>, d: f64) -> bool {
    let m = nalgebra::center(a, b);
    let cm = (c - m).norm();
    let am = (a - m).norm();
    if cm < am {
        return true;
    }
    match circumcentre(a, b, c) {
        Some(o) => (o - m).norm() < d,
        None => false,
    }
}

/// §3.2 edge test for node C and edge AB, as the paper states its intent: "AB crossing or
/// being very close (less than d) to R", R = {X : |XC| ≤ |XA|, |XC| ≤ |XB|}.
///
/// Crossing is `[CM] < [AM]` with M the midpoint of AB (see the module docs). Closeness is
/// tested with a lower bound of the distance from AB to R: for X on AB, dist(X, R) ≥
/// max(dist(X, H_A), dist(X, H_B)), H_A and H_B the half-spaces closer to C than to A and to
/// B. That bound is convex and piecewise linear along AB, so its minimum is at an end or where
/// the two distances are equal. Adding AB when the bound is below d never misses an edge
/// within d of R (it may add a few more than strictly needed). It accepts every edge that the
/// printed `[OM] < d` accepts, since O is in R and M on AB.
pub fn edge_needs_check(c: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>, d: f64) -> bool {
    let m = nalgebra::center(a, b);
    if (c - m).norm() < (a - m).norm() {
        return true;
    }
    let (ca, cb) = (a - c, b - c);
    let (la, lb) = (ca.norm(), cb.norm());
    if la == 0.0 || lb == 0.0 {
        return true;
    }
    // Signed distance of X(t) = A + t (B − A) to the bisector plane of AC (positive: closer
    // to A), and likewise for BC; both affine in t.
    let mid_a = nalgebra::center(a, c);
    let mid_b = nalgebra::center(b, c);
    let ga = |x: &Point3<f64>| (x - mid_a).dot(&ca) / la;
    let gb = |x: &Point3<f64>| (x - mid_b).dot(&cb) / lb;
    let (ga0, ga1, gb0, gb1) = (ga(a), ga(b), gb(a), gb(b));
    let f = |t: f64| f64::max((ga0 + t * (ga1 - ga0)).max(gb0 + t * (gb1 - gb0)), 0.0);
    let mut best = f(0.0).min(f(1.0));
    let denom = (ga1 - ga0) - (gb1 - gb0);
    if denom != 0.0 {
        let t = (gb0 - ga0) / denom;
        if (0.0..=1.0).contains(&t) {
            best = best.min(f(t));
        }
    }
    best < d
}

/// §3.2 face test for node C and face T₁T₂T₃ with unit outward normal `n`, as printed: the
/// circumsphere discard `[CR] > 2·[T₁R]`, then eq. (2) on S = {D₁, D₂, D₃, E₁, E₂, E₃, O₁}.
///
/// The discard is exact for points of the face itself but not for points up to d away from
/// it, and seven sample points of the displaced triangle can all miss R while R still meets
/// the layer of points within d of the face: our brute-force comparison finds slaves (mostly
/// inside, with C behind the face plane) whose closest face this test leaves out. See
/// [`face_needs_check`].
pub fn face_needs_check_literal(
    c: &Point3<f64>,
    t: [&Point3<f64>; 3],
    n: &Vector3<f64>,
    d: f64,
) -> bool {
    let Some(r) = circumcentre(t[0], t[1], t[2]) else { return false };
    let rho = (t[0] - r).norm();
    if (c - r).norm() > 2.0 * rho {
        return false;
    }
    let side = if (c - t[0]).dot(n) >= 0.0 { *n } else { -*n };
    let dn = side * d;
    let dp = [t[0] + dn, t[1] + dn, t[2] + dn];
    let mid = [nalgebra::center(c, t[0]), nalgebra::center(c, t[1]), nalgebra::center(c, t[2])];
    let in_region = |s: &Point3<f64>| (0..3).all(|i| (s - mid[i]).dot(&(c - mid[i])) > 0.0);
    if dp.iter().any(in_region) {
        return true;
    }
    for i in 0..3 {
        if in_region(&nalgebra::center(&dp[i], &dp[(i + 1) % 3])) {
            return true;
        }
    }
    let o1 = r + dn;
    project_inside_triangle(&o1, &dp[0], &dp[1], &dp[2], &side).is_some() && in_region(&o1)
}

/// §3.2 face test for node C and face T₁T₂T₃ (unit normal `n`), as the paper states its
/// purpose: can a point within d of the face's interior (either side) be closer to C than
/// to T₁, T₂ and T₃? The discard becomes `[CR] > 2·√(ρ² + d²)` (a point X + s·n with X in the
/// face and |s| ≤ d is within √(ρ² + d²) of its nearest vertex and at least
/// |CR| − √(ρ² + d²) from C). The remaining question — does the polytope
/// {X + s·n : X ∈ T, |s| ≤ d} ∩ {closer to C than to each T_i} have a point — is a
/// 3-variable linear feasibility problem (barycentric λ₁, λ₂ and height s; eight
/// inequalities); a bounded non-empty polytope has a vertex, so we try every vertex
/// candidate (three inequalities active) and accept the face if one satisfies all eight
/// within a relative 1e-9 (accepting a little too much is harmless).
pub fn face_needs_check(c: &Point3<f64>, t: [&Point3<f64>; 3], n: &Vector3<f64>, d: f64) -> bool {
    let Some(r) = circumcentre(t[0], t[1], t[2]) else { return false };
    let rho = (t[0] - r).norm();
    if (c - r).norm() > 2.0 * (rho * rho + d * d).sqrt() {
        return false;
    }
    // Quick answers: the printed test's sample points lie in the layer, so its acceptance
    // is a witness; and if some half-space "closer to C than T_i" misses all six corners of
    // the layer (an affine function's maximum over a polytope is at a corner), nothing in
    // the layer is in R.
    if face_needs_check_literal(c, t, n, d) {
        return true;
    }
    let corners =
        [t[0] + n * d, t[1] + n * d, t[2] + n * d, t[0] - n * d, t[1] - n * d, t[2] - n * d];
    for ti in t {
        let mi = nalgebra::center(c, ti);
        let u = c - mi;
        if corners.iter().all(|x| (x - mi).dot(&u) < 0.0) {
            return false;
        }
    }
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    // Rows a·z ≤ b over z = (λ₁, λ₂, s), each normalised.
    let mut rows: [(Vector3<f64>, f64); 8] = [(Vector3::zeros(), 0.0); 8];
    rows[0] = (Vector3::new(-1.0, 0.0, 0.0), 0.0);
    rows[1] = (Vector3::new(0.0, -1.0, 0.0), 0.0);
    rows[2] = (Vector3::new(1.0, 1.0, 0.0) / 2f64.sqrt(), 1.0 / 2f64.sqrt());
    rows[3] = (Vector3::new(0.0, 0.0, 1.0), d);
    rows[4] = (Vector3::new(0.0, 0.0, -1.0), d);
    for i in 0..3 {
        // (X − M_i) · u_i ≥ 0 with u_i = C − M_i, X = T₁ + λ₁ e₁ + λ₂ e₂ + s n.
        let mi = nalgebra::center(c, t[i]);
        let u = c - mi;
        let a = -Vector3::new(e1.dot(&u), e2.dot(&u), n.dot(&u));
        let b = (t[0] - mi).dot(&u);
        let len = a.norm();
        if len == 0.0 {
            return true;
        }
        rows[5 + i] = (a / len, b / len);
    }
    let scale = 1e-9 * (1.0 + d / e1.norm().max(e2.norm()));
    for i in 0..8 {
        for j in i + 1..8 {
            for k in j + 1..8 {
                let m = nalgebra::Matrix3::from_rows(&[
                    rows[i].0.transpose(),
                    rows[j].0.transpose(),
                    rows[k].0.transpose(),
                ]);
                let Some(inv) = m.try_inverse() else { continue };
                let z = inv * Vector3::new(rows[i].1, rows[j].1, rows[k].1);
                if !z.iter().all(|x| x.is_finite()) {
                    continue;
                }
                if rows.iter().all(|(a, b)| a.dot(&z) <= b + scale * (1.0 + z.norm())) {
                    return true;
                }
            }
        }
    }
    false
}

/// Builds the additional lists for every used master node with penetration bound `d`.
pub fn build_lists(m: &MasterSurface, d: f64, literal: bool) -> AdditionalLists {
    let nv = m.vertices().len();
    // Edges bucketed by midpoint, bucket size half the longest edge.
    let edge_items: Vec<(u32, Point3<f64>)> = m
        .edges()
        .iter()
        .enumerate()
        .map(|(e, ab)| {
            (
                e as u32,
                nalgebra::center(&m.vertices()[ab[0] as usize], &m.vertices()[ab[1] as usize]),
            )
        })
        .collect();
    let edge_grid = BucketGrid::new(&edge_items, Vector3::repeat(0.5 * m.max_edge()));
    // Faces bucketed by circumcentre, bucket size the largest circumradius.
    let mut rho_max = 0.0f64;
    let face_items: Vec<(u32, Point3<f64>)> = m
        .triangles()
        .iter()
        .enumerate()
        .map(|(f, t)| {
            let (a, b, c) = (
                &m.vertices()[t[0] as usize],
                &m.vertices()[t[1] as usize],
                &m.vertices()[t[2] as usize],
            );
            let r = circumcentre(a, b, c)
                .unwrap_or_else(|| Point3::from((a.coords + b.coords + c.coords) / 3.0));
            rho_max = rho_max.max((a - r).norm());
            (f as u32, r)
        })
        .collect();
    let face_grid = BucketGrid::new(&face_items, Vector3::repeat(rho_max));

    let mut lists = AdditionalLists {
        edge_start: Vec::with_capacity(nv + 1),
        face_start: Vec::with_capacity(nv + 1),
        ..Default::default()
    };
    lists.edge_start.push(0);
    lists.face_start.push(0);
    let edge_radius = m.max_edge() + 2.0 * d;
    let edge_test = if literal { edge_needs_check_literal } else { edge_needs_check };
    let face_test = if literal { face_needs_check_literal } else { face_needs_check };
    let face_radius =
        if literal { 2.0 * rho_max } else { 2.0 * (rho_max * rho_max + d * d).sqrt() };
    for c in 0..nv as u32 {
        if m.is_used(c) {
            let pc = &m.vertices()[c as usize];
            let first_edge = lists.edges.len();
            edge_grid.for_each_in_box(pc, edge_radius, |e, _| {
                let ab = m.edges()[e as usize];
                if ab.contains(&c) {
                    return;
                }
                let shares_face = m.edge_faces()[e as usize]
                    .iter()
                    .any(|&f| m.triangles()[f as usize].contains(&c));
                if shares_face && literal {
                    return;
                }
                if edge_test(pc, &m.vertices()[ab[0] as usize], &m.vertices()[ab[1] as usize], d) {
                    lists.edges.push(e);
                }
            });
            lists.edges[first_edge..].sort_unstable();
            let first_face = lists.faces.len();
            face_grid.for_each_in_box(pc, face_radius, |f, _| {
                let t = m.triangles()[f as usize];
                if t.contains(&c) {
                    return;
                }
                let tp = [
                    &m.vertices()[t[0] as usize],
                    &m.vertices()[t[1] as usize],
                    &m.vertices()[t[2] as usize],
                ];
                if face_test(pc, tp, &m.face_normals()[f as usize], d) {
                    lists.faces.push(f);
                }
            });
            lists.faces[first_face..].sort_unstable();
        }
        lists.edge_start.push(lists.edges.len() as u32);
        lists.face_start.push(lists.faces.len() as u32);
    }
    lists
}

/// Per-face data for the projection test: a vertex, the unit normal and the three in-plane
/// inward edge normals with offsets (P projects inside ⇔ `m_k · P ≥ off_k` for k = 0, 1, 2,
/// since each m_k is perpendicular to the face normal).
#[derive(Debug, Clone, Copy)]
pub(crate) struct FaceData {
    a: Point3<f64>,
    n: Vector3<f64>,
    m: [Vector3<f64>; 3],
    off: [f64; 3],
}

impl FaceData {
    fn new(m: &MasterSurface, f: usize) -> Self {
        let t = m.triangles()[f];
        let v =
            [m.vertices()[t[0] as usize], m.vertices()[t[1] as usize], m.vertices()[t[2] as usize]];
        let n = m.face_normals()[f];
        let mut mm = [Vector3::zeros(); 3];
        let mut off = [0.0; 3];
        for k in 0..3 {
            mm[k] = n.cross(&(v[(k + 1) % 3] - v[k]));
            off[k] = mm[k].dot(&v[k].coords);
        }
        Self { a: v[0], n, m: mm, off }
    }

    /// Projection of `p` on the face plane when it lies inside the closed triangle.
    #[inline]
    fn project_inside(&self, p: &Point3<f64>) -> Option<Point3<f64>> {
        let c = &p.coords;
        if self.m[0].dot(c) >= self.off[0]
            && self.m[1].dot(c) >= self.off[1]
            && self.m[2].dot(c) >= self.off[2]
        {
            Some(p - self.n * (p - self.a).dot(&self.n))
        } else {
            None
        }
    }
}

/// An edge at a node C, seen from C: the other end E, E − C and |E − C|².
#[derive(Debug, Clone, Copy)]
pub(crate) struct EdgeAt {
    edge: u32,
    dir: Vector3<f64>,
    len2: f64,
}

/// A face at a node C with the bisector of its angle at C.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FaceAt {
    face: u32,
    bisector: Vector3<f64>,
    data: FaceData,
}

/// An additional edge of a node: one end A, B − A and |B − A|².
#[derive(Debug, Clone, Copy)]
pub(crate) struct EdgeSeg {
    edge: u32,
    a: Point3<f64>,
    dir: Vector3<f64>,
    len2: f64,
}

/// Most neighbours kept per master node for certifying the closest-node search.
const NEAR: usize = 64;

/// The paper's contact handler.
#[derive(Debug, Clone)]
pub struct PaperContact {
    pub(crate) master: Arc<MasterSurface>,
    pub(crate) grid: BucketGrid,
    pub(crate) lists: AdditionalLists,
    pub(crate) d: f64,
    pub(crate) d2: f64,
    pub(crate) radius2: Vec<f64>,
    /// CSR per node: faces at the node with their bisectors.
    faces_at_start: Vec<u32>,
    faces_at: Vec<FaceAt>,
    /// CSR per node: edges at the node, then the node's additional edges (as A→B).
    edges_at_start: Vec<u32>,
    edges_at: Vec<EdgeAt>,
    /// The additional edges of each node (indexed like `lists.edges`), ready to project on.
    list_edges: Vec<EdgeSeg>,
    /// The additional faces of each node (indexed like `lists.faces`).
    list_faces: Vec<FaceData>,
    /// CSR per node: the nearest other used nodes (at most [`NEAR`]), sorted by distance.
    near_start: Vec<u32>,
    near: Vec<(f64, u32)>,
    /// Per node: every used node not in its list is at least this far.
    near_radius: Vec<f64>,
    /// Per bucket: a node near the bucket centre (start of the certification when the
    /// 27-bucket block is empty).
    seeds: Vec<u32>,
}

impl PaperContact {
    /// Validates the skull and runs the preprocessing stage.
    pub fn new(surface: &TriSurface, params: PaperParams) -> Result<Self, ContactError> {
        Self::from_master(Arc::new(MasterSurface::new(surface)?), params)
    }

    /// Runs the preprocessing on an already validated (shared) master surface.
    pub fn from_master(
        master: Arc<MasterSurface>,
        params: PaperParams,
    ) -> Result<Self, ContactError> {
        let d = params.max_step_penetration.unwrap_or(0.25 * master.max_edge());
        if !(d.is_finite() && d >= 0.0) {
            return Err(ContactError::InvalidParameter(format!(
                "max_step_penetration must be finite and ≥ 0, got {d}"
            )));
        }
        // Master nodes bucketed with per-axis size = half the largest edge projection.
        let items: Vec<(u32, Point3<f64>)> = (0..master.vertices().len() as u32)
            .filter(|&v| master.is_used(v))
            .map(|v| (v, master.vertices()[v as usize]))
            .collect();
        let grid = BucketGrid::new(&items, master.max_edge_projection() * 0.5);
        let lists = if params.additional_lists {
            build_lists(&master, d, params.literal_list_tests)
        } else {
            let nv = master.vertices().len();
            AdditionalLists {
                edge_start: vec![0; nv + 1],
                face_start: vec![0; nv + 1],
                ..Default::default()
            }
        };
        let radius2 = master.node_radius().iter().map(|r| r * r).collect();
        let nv = master.vertices().len();
        let mut faces_at_start = Vec::with_capacity(nv + 1);
        let mut faces_at = Vec::with_capacity(3 * master.triangles().len());
        let mut edges_at_start = Vec::with_capacity(nv + 1);
        let mut edges_at = Vec::with_capacity(2 * master.edges().len());
        faces_at_start.push(0);
        edges_at_start.push(0);
        for c in 0..nv as u32 {
            for &f in master.faces_of(c) {
                let t = master.triangles()[f as usize];
                let k = t.iter().position(|&x| x == c).unwrap_or(0);
                faces_at.push(FaceAt {
                    face: f,
                    bisector: master.bisectors()[f as usize][k],
                    data: FaceData::new(&master, f as usize),
                });
            }
            for &e in master.edges_of(c) {
                let ab = master.edges()[e as usize];
                let other = if ab[0] == c { ab[1] } else { ab[0] };
                let dir = master.vertices()[other as usize] - master.vertices()[c as usize];
                edges_at.push(EdgeAt { edge: e, dir, len2: dir.norm_squared() });
            }
            faces_at_start.push(faces_at.len() as u32);
            edges_at_start.push(edges_at.len() as u32);
        }
        let list_edges = lists
            .edges
            .iter()
            .map(|&e| {
                let ab = master.edges()[e as usize];
                let a = master.vertices()[ab[0] as usize];
                let dir = master.vertices()[ab[1] as usize] - a;
                EdgeSeg { edge: e, a, dir, len2: dir.norm_squared() }
            })
            .collect();
        let list_faces = lists.faces.iter().map(|&f| FaceData::new(&master, f as usize)).collect();
        // Node neighbourhoods for certifying the block search: the nearest (at most NEAR)
        // nodes within three longest edges.
        let gather = 3.0 * master.max_edge();
        let mut near_start = Vec::with_capacity(nv + 1);
        let mut near = Vec::new();
        let mut near_radius = vec![0.0; nv];
        near_start.push(0u32);
        let mut found: Vec<(f64, u32)> = Vec::new();
        for c in 0..nv as u32 {
            if master.is_used(c) {
                let pc = master.vertices()[c as usize];
                found.clear();
                grid.for_each_in_box(&pc, gather, |id, q| {
                    let dist = (q - pc).norm();
                    if id != c && dist < gather {
                        found.push((dist, id));
                    }
                });
                found.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                let keep = found.len().min(NEAR);
                near_radius[c as usize] = if keep < found.len() { found[keep].0 } else { gather };
                near.extend_from_slice(&found[..keep]);
            }
            near_start.push(near.len() as u32);
        }
        let seeds = grid.seeds();
        Ok(Self {
            master,
            grid,
            lists,
            d,
            d2: d * d,
            radius2,
            faces_at_start,
            faces_at,
            edges_at_start,
            edges_at,
            list_edges,
            list_faces,
            near_start,
            near,
            near_radius,
            seeds,
        })
    }

    /// The master surface.
    pub fn master(&self) -> &MasterSurface {
        &self.master
    }

    /// The additional lists.
    pub fn lists(&self) -> &AdditionalLists {
        &self.lists
    }

    /// The node bucket grid.
    pub fn grid(&self) -> &BucketGrid {
        &self.grid
    }

    /// The per-step penetration bound d.
    pub fn max_step_penetration(&self) -> f64 {
        self.d
    }

    /// Exact closest master node (global search), ties to the smallest node index; `None`
    /// for a non-finite point.
    ///
    /// The paper's search: P's bucket and its 26 neighbours. Our certification that the
    /// node C found there is the closest: if every unvisited bucket is farther than C, done;
    /// otherwise (C = a precomputed seed node of P's bucket when the block is empty) every
    /// node N closer to P than C has |CN| ≤ |CP| + |PN| ≤ 2|CP|, so scanning
    /// C's precomputed neighbourhood (its nearest ≤ 64 nodes within three longest edges, sorted
    /// by distance) up to 2|CP| is exact when that covers 2|CP|; beyond that (P far from the skull) the bucket search widens until
    /// certified ([`BucketGrid::nearest`]).
    #[inline]
    pub fn closest_node(&self, p: &Point3<f64>) -> Option<u32> {
        if !p.coords.iter().all(|x| x.is_finite()) {
            return None;
        }
        let b = self.grid.block(p);
        if b.best.1 < b.bound * b.bound {
            return Some(b.best.0);
        }
        // Start from the block's nearest, or from the bucket's seed when the block is empty.
        let (start, start_d2) = if b.best.1.is_finite() {
            b.best
        } else {
            let id = self.seeds[self.grid.flat_of(p)];
            if id == u32::MAX {
                return self.grid.nearest_from(p, b, false).map(|n| n.id);
            }
            (id, (self.master.vertices()[id as usize] - p).norm_squared())
        };
        let c = start as usize;
        let limit = 2.0 * start_d2.sqrt() * (1.0 + 1e-12);
        if limit < self.near_radius[c] {
            let mut best = (start, start_d2);
            let mut next = f64::INFINITY;
            for &(dist, id) in
                &self.near[self.near_start[c] as usize..self.near_start[c + 1] as usize]
            {
                if dist > limit {
                    break;
                }
                let d2 = (self.master.vertices()[id as usize] - p).norm_squared();
                crate::grid::consider(id, d2, &mut best, &mut next);
            }
            return Some(best.0);
        }
        self.grid.nearest_from(p, b, false).map(|n| n.id)
    }

    /// Local search around closest node `c`, verdict included. `None` when no candidate
    /// remains (eq. (1) skipped the basic tests and no additional feature applies).
    #[inline]
    pub fn local_search(&self, c: u32, p: &Point3<f64>) -> Option<Projection> {
        let m = &*self.master;
        let ci = c as usize;
        let pc = &m.vertices()[ci];
        let cp = p - pc;
        let mut best_d2 = f64::INFINITY;
        let mut best: Option<(Point3<f64>, Feature)> = None;
        let mut offer = |r: Point3<f64>, f: Feature| {
            let d2 = (p - r).norm_squared();
            if d2 < best_d2 {
                best_d2 = d2;
                best = Some((r, f));
            }
        };
        if cp.norm_squared() <= self.d2 + self.radius2[ci] {
            let fa = &self.faces_at
                [self.faces_at_start[ci] as usize..self.faces_at_start[ci + 1] as usize];
            for f in fa {
                if cp.dot(&f.bisector) > 0.0
                    && let Some(r) = f.data.project_inside(p)
                {
                    offer(r, Feature::Face(f.face));
                }
            }
            let ea = &self.edges_at
                [self.edges_at_start[ci] as usize..self.edges_at_start[ci + 1] as usize];
            for e in ea {
                let t = cp.dot(&e.dir);
                if t >= 0.0 && t <= e.len2 {
                    offer(pc + e.dir * (t / e.len2), Feature::Edge(e.edge));
                }
            }
            offer(*pc, Feature::Node(c));
        }
        let (es, ee) = (self.lists.edge_start[ci] as usize, self.lists.edge_start[ci + 1] as usize);
        for e in &self.list_edges[es..ee] {
            let t = (p - e.a).dot(&e.dir);
            if t >= 0.0 && t <= e.len2 {
                offer(e.a + e.dir * (t / e.len2), Feature::Edge(e.edge));
            }
        }
        let (fs, fe) = (self.lists.face_start[ci] as usize, self.lists.face_start[ci + 1] as usize);
        for (f, data) in self.lists.faces[fs..fe].iter().zip(&self.list_faces[fs..fe]) {
            if let Some(r) = data.project_inside(p) {
                offer(r, Feature::Face(*f));
            }
        }
        let (r, f) = best?;
        Some(m.projection(p, r, best_d2, f))
    }

    /// Global search then local search.
    #[inline]
    pub fn project(&self, p: &Point3<f64>) -> Option<Projection> {
        let c = self.closest_node(p)?;
        self.local_search(c, p)
    }

    /// The exact closest point of the surface at any distance, with its feature and the
    /// paper's verdict; `None` only for a non-finite point.
    ///
    /// Within `d` of the surface the paper's search is exact ([`project`](Self::project)).
    /// Farther away: the closest point R satisfies `|PR| ≤ |PC|` for the closest node C, and
    /// every vertex of a face containing R lies within `|PR| + L_max` of P, so the faces of
    /// the nodes in that box contain R; each is tested exactly.
    pub fn project_exact(&self, p: &Point3<f64>) -> Option<Projection> {
        let c = self.closest_node(p)?;
        if let Some(proj) = self.local_search(c, p)
            && proj.signed_distance.abs() <= self.d
        {
            return Some(proj);
        }
        let m = &*self.master;
        let radius = (p - m.vertices()[c as usize]).norm() + m.max_edge();
        let mut faces: Vec<u32> = Vec::new();
        self.grid.for_each_in_box(p, radius, |id, _| {
            for &t in m.faces_of(id) {
                if !faces.contains(&t) {
                    faces.push(t);
                }
            }
        });
        m.project_on_faces(p, faces)
    }
}

impl ClosestPoint for PaperContact {
    fn closest(&mut self, _slave: usize, p: &Point3<f64>) -> Option<Projection> {
        self.project(p)
    }

    fn reach(&self) -> f64 {
        self.d
    }

    fn closest_exact(&self, p: &Point3<f64>) -> Option<Projection> {
        self.project_exact(p)
    }

    fn name(&self) -> &'static str {
        "paper"
    }
}
