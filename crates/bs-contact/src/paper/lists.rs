//! The paper's additional lists (§3.2): for each skull node, the edges and faces a slave
//! whose closest skull node it is may penetrate without containing that node, with the
//! predicates that decide it.

use nalgebra::{Point3, Vector3};

use crate::geometry::{circumcentre, project_inside_triangle};
use crate::grid::BucketGrid;
use crate::master::MasterSurface;

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
