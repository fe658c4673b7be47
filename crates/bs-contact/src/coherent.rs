//! Temporal coherence on top of the paper's algorithm (our addition).
//!
//! Dynamic Relaxation moves nodes by tiny amounts per step. For each slave we keep an
//! *anchor* position A where the paper's algorithm last ran, its closest master node C and
//! two certified margins; while the slave stays within them of A we skip work whose result
//! is known:
//!
//! * **Node margin.** At A, C is the closest node at distance d₁ and every other node is at
//!   least L away (the bucket search certifies L). If the slave is now at P with
//!   δ = |P − A| < (L − d₁)/2, then |PC| ≤ d₁ + δ < L − δ ≤ |PN| for every other node N
//!   (triangle inequality), so C is still the unique closest node and the global search is
//!   skipped. The paper's local search then runs on the same (C, P) with the same code,
//!   giving a bit-identical answer. The anchor moves to P with d₁ = |PC|, L ← L − δ.
//! * **Inside margin.** The paper's verdict for closest node C is `s_F(P) = (P − X_F) · n_F > 0`
//!   for the winning candidate feature F (face, edge, node around C or in C's additional
//!   lists; X_F any point of F's plane or line, since n_F is perpendicular to F). Each
//!   `s_F` is an affine function of P with gradient n_F. If at the anchor every candidate
//!   has `s_F(A) < 0`, let μ = min_F (−s_F(A) / |n_F|); for δ < μ every candidate still
//!   says inside, whichever wins, so the paper applies no correction; if also δ is within
//!   the node margin (same C, same candidates) nothing needs computing at all.
//!
//! * **Neighbour list.** When the node margin is exceeded, the closest node is looked up in
//!   the slave's neighbour list instead of the bucket grid: at its last bucket search (at
//!   A') the slave kept the ≤ 16 nodes nearest to A' within (closest distance + one longest
//!   edge), and ρ, a bound such that every node not in the list is at least ρ from A'. At P
//!   with δ' = |P − A'|, let d₁ be the distance to the nearest list node; the true closest
//!   node N has |A'N| ≤ δ' + |PN| ≤ δ' + d₁, so if δ' + d₁ < ρ it is in the list and the list
//!   minimum is exact. An exact tie in the list falls back to the bucket search, so the node
//!   chosen is always the one the paper handler's search returns.
//!
//! Both margins are shrunk by a relative 1e-9 (the inside margin also by 1e-12 of the model
//! size) so that rounding can never make them
//! optimistic. Hence every correction equals the paper handler's, on every step (tested
//! over random walks).

use std::sync::Arc;

use bs_mesh::TriSurface;
use nalgebra::{Point3, Vector3};

use crate::ContactError;
use crate::master::MasterSurface;
use crate::paper::{PaperContact, PaperParams};
use crate::query::{ClosestPoint, Projection};

/// Per-slave cached state.
#[derive(Debug, Clone, Copy)]
struct Anchor {
    at: Point3<f64>,
    c: u32,
    /// Lower bound on the distance from `at` to every master node other than `c`.
    other_lb: f64,
    /// δ² below which `c` is still the closest node.
    node_margin2: f64,
    /// δ² below which the paper applies no correction (0 when not certified inside).
    skip_margin2: f64,
}

/// Most master nodes kept in a slave's neighbour list.
const LIST: usize = 16;

/// Per-slave neighbour list ("Verlet list" with a skin): the master nodes nearest to the
/// list's anchor; every node not in it is at least `rho` from the anchor.
#[derive(Debug, Clone, Copy)]
struct NodeList {
    at: Point3<f64>,
    rho: f64,
    len: u8,
    nodes: [u32; LIST],
}

/// Shrink factor applied to certified margins (guards against rounding).
const SAFETY: f64 = 1.0 - 1e-9;

/// The paper's algorithm with per-slave temporal coherence; same corrections as
/// [`PaperContact`] on every step.
#[derive(Debug, Clone)]
pub struct CoherentContact {
    paper: PaperContact,
    /// Per used node: CSR of candidate verdict planes (unit normal, offset) — faces, edges and
    /// the node itself around C plus C's additional lists.
    plane_start: Vec<u32>,
    planes: Vec<(Vector3<f64>, f64)>,
    anchors: Vec<Option<Anchor>>,
    lists: Vec<Option<NodeList>>,
    /// Radius beyond the closest node out to which neighbour lists are gathered.
    skin: f64,
    /// Absolute slack subtracted from the inside margin: 1e-12 of the model size, far above
    /// the rounding of the verdict's dot products.
    abs_slack: f64,
    /// Statistics: full (global) searches, local-only searches, skipped queries.
    stats: CoherenceStats,
}

/// How often each path ran.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CoherenceStats {
    /// Queries that ran the global bucket search.
    pub global: u64,
    /// Queries that found the closest node in the slave's neighbour list.
    pub list: u64,
    /// Queries that reused the closest node and ran only the local search.
    pub local: u64,
    /// Queries certified inside without any search.
    pub skipped: u64,
}

impl CoherentContact {
    /// Validates the skull and runs the paper's preprocessing plus the coherence tables.
    pub fn new(surface: &TriSurface, params: PaperParams) -> Result<Self, ContactError> {
        Ok(Self::from_paper(PaperContact::new(surface, params)?))
    }

    /// Builds on an already validated master surface.
    pub fn from_master(
        master: Arc<MasterSurface>,
        params: PaperParams,
    ) -> Result<Self, ContactError> {
        Ok(Self::from_paper(PaperContact::from_master(master, params)?))
    }

    /// Wraps a prepared paper handler.
    pub fn from_paper(paper: PaperContact) -> Self {
        let m = paper.master.clone();
        let unit = |n: &Vector3<f64>| {
            let len = n.norm();
            if len > 0.0 { n / len } else { Vector3::zeros() }
        };
        let mut plane_start = vec![0u32];
        let mut planes = Vec::new();
        for c in 0..m.vertices().len() as u32 {
            let mut push = |n: &Vector3<f64>, x: &Point3<f64>| {
                let u = unit(n);
                planes.push((u, u.dot(&x.coords)));
            };
            if m.is_used(c) {
                for &f in m.faces_of(c).iter().chain(paper.lists.faces_of(c)) {
                    push(
                        &m.face_normals()[f as usize],
                        &m.vertices()[m.triangles()[f as usize][0] as usize],
                    );
                }
                for &e in m.edges_of(c).iter().chain(paper.lists.edges_of(c)) {
                    push(
                        &m.edge_normals()[e as usize],
                        &m.vertices()[m.edges()[e as usize][0] as usize],
                    );
                }
                push(&m.node_normals()[c as usize], &m.vertices()[c as usize]);
            }
            plane_start.push(planes.len() as u32);
        }
        let abs_slack = 1e-12 * m.size();
        let skin = m.max_edge();
        Self {
            paper,
            plane_start,
            planes,
            anchors: Vec::new(),
            lists: Vec::new(),
            skin,
            abs_slack,
            stats: CoherenceStats::default(),
        }
    }

    /// The wrapped paper handler.
    pub fn paper(&self) -> &PaperContact {
        &self.paper
    }

    /// How often each path ran since construction (or the last [`reset`](Self::reset)).
    pub fn stats(&self) -> CoherenceStats {
        self.stats
    }

    /// Forgets all cached state.
    pub fn reset(&mut self) {
        self.anchors.clear();
        self.lists.clear();
        self.stats = CoherenceStats::default();
    }

    /// Certified distance (δ) from `p` within which every candidate plane of `c` says
    /// inside; 0 when some candidate does not.
    #[inline]
    fn inside_margin(&self, c: u32, p: &Point3<f64>) -> f64 {
        let s = self.plane_start[c as usize] as usize;
        let e = self.plane_start[c as usize + 1] as usize;
        let mut mu = f64::INFINITY;
        for (u, off) in &self.planes[s..e] {
            let gap = off - u.dot(&p.coords);
            if gap < mu {
                mu = gap;
                if mu <= 0.0 {
                    return 0.0;
                }
            }
        }
        mu
    }

    #[inline]
    fn anchor_at(&self, p: &Point3<f64>, c: u32, other_lb: f64, outside: bool) -> Anchor {
        let d1 = (p - self.paper.master.vertices()[c as usize]).norm();
        let node_margin = (0.5 * (other_lb - d1) * SAFETY).max(0.0);
        let skip = if outside {
            0.0
        } else {
            ((self.inside_margin(c, p) - self.abs_slack) * SAFETY).clamp(0.0, node_margin)
        };
        Anchor {
            at: *p,
            c,
            other_lb,
            node_margin2: node_margin * node_margin,
            skip_margin2: skip * skip,
        }
    }
}

impl CoherentContact {
    /// Gathers the neighbour list of a slave at `p` whose closest node is at distance `d1`:
    /// the (at most [`LIST`]) nodes nearest to `p` within `d1 + skin`.
    fn gather(&self, p: &Point3<f64>, d1: f64) -> NodeList {
        let reach = d1 + self.skin;
        let mut found: [(f64, u32); 64] = [(f64::INFINITY, 0); 64];
        let mut n = 0usize;
        let mut overflow = f64::INFINITY;
        self.paper.grid.for_each_in_box(p, reach, |id, q| {
            let d = (q - p).norm();
            if d >= reach {
                return;
            }
            if n < found.len() {
                found[n] = (d, id);
                n += 1;
            } else {
                overflow = overflow.min(d);
            }
        });
        let found = &mut found[..n];
        found.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let keep = n.min(LIST);
        // Nodes not kept: beyond `reach`, the overflowed ones, the sorted tail.
        let mut rho = reach.min(overflow);
        if keep < n {
            rho = rho.min(found[keep].0);
        }
        let mut nodes = [0u32; LIST];
        for (k, f) in found[..keep].iter().enumerate() {
            nodes[k] = f.1;
        }
        NodeList { at: *p, rho: rho * SAFETY, len: keep as u8, nodes }
    }

    /// Exact closest node from the slave's neighbour list, with a lower bound on the
    /// distance to every other node; `None` when the list cannot certify it or on an exact
    /// tie (then the bucket search decides, as in the paper's handler).
    #[inline]
    fn nearest_in_list(&self, l: &NodeList, p: &Point3<f64>) -> Option<(u32, f64)> {
        let delta = (p - l.at).norm() / SAFETY;
        let verts = &self.paper.master.vertices();
        let mut best = (u32::MAX, f64::INFINITY);
        let mut next = f64::INFINITY;
        for &id in &l.nodes[..l.len as usize] {
            let d2 = (verts[id as usize] - p).norm_squared();
            if d2 < best.1 {
                next = best.1;
                best = (id, d2);
            } else if d2 < next {
                next = d2;
            }
        }
        let d1 = best.1.sqrt();
        // The true closest node N has |A N| ≤ |A P| + |P N| ≤ δ + d1 < ρ: it is in the list.
        let certified = d1 + delta < l.rho;
        if !certified || next == best.1 {
            return None;
        }
        Some((best.0, next.sqrt().min(l.rho - delta)))
    }
}

impl ClosestPoint for CoherentContact {
    #[inline]
    fn closest(&mut self, slave: usize, p: &Point3<f64>) -> Option<Projection> {
        if slave >= self.anchors.len() {
            self.anchors.resize(slave + 1, None);
            self.lists.resize(slave + 1, None);
        }
        if let Some(a) = self.anchors[slave] {
            let delta2 = (p - a.at).norm_squared();
            if delta2 < a.skip_margin2 {
                self.stats.skipped += 1;
                return None;
            }
            if delta2 < a.node_margin2 {
                self.stats.local += 1;
                let proj = self.paper.local_search(a.c, p);
                let outside = proj.is_some_and(|q| q.outside);
                let lb = a.other_lb - delta2.sqrt() / SAFETY;
                self.anchors[slave] = Some(self.anchor_at(p, a.c, lb, outside));
                return proj;
            }
        }
        if let Some(l) = self.lists[slave]
            && let Some((c, other_lb)) = self.nearest_in_list(&l, p)
        {
            self.stats.list += 1;
            let proj = self.paper.local_search(c, p);
            let outside = proj.is_some_and(|q| q.outside);
            self.anchors[slave] = Some(self.anchor_at(p, c, other_lb * SAFETY, outside));
            return proj;
        }
        self.stats.global += 1;
        let n = self.paper.grid.nearest(p, true)?;
        let proj = self.paper.local_search(n.id, p);
        let outside = proj.is_some_and(|q| q.outside);
        self.anchors[slave] = Some(self.anchor_at(p, n.id, n.other_lb * SAFETY, outside));
        self.lists[slave] = Some(self.gather(p, n.d2.sqrt()));
        proj
    }

    fn reach(&self) -> f64 {
        self.paper.d
    }

    fn closest_exact(&self, p: &Point3<f64>) -> Option<Projection> {
        self.paper.project_exact(p)
    }

    fn name(&self) -> &'static str {
        "coherent"
    }
}
