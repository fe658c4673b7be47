//! Isosurface stuffing (Labelle & Shewchuk, "Isosurface Stuffing: Fast Tetrahedral Meshes
//! with Good Dihedral Angles", SIGGRAPH 2007), written from the paper.
//!
//! 1. The domain `{f < 0}` is covered by a BCC lattice ([`Bcc`]); `f` is evaluated at
//!    every lattice vertex.
//! 2. Every lattice edge with one negative and one positive end gets a *cut point*, the
//!    root of `f` along the edge (regula falsi, Illinois variant).
//! 3. *Warping*: a cut point closer to an end `v` than `α · |edge|` (α = `α_long` on long
//!    edges, `α_short` on short ones) *violates* `v`; every violated vertex moves to its
//!    nearest violating cut point, becomes a zero vertex, and the cut points of its edges
//!    disappear. Vertices are processed in id order (deterministic).
//! 4. *Stencils*: every lattice tetrahedron contributes its negative part
//!    ([`fill_negative`]). Quadrilateral faces are split by the paper's rules, which depend
//!    only on the face: on a face whose long edge joins the outside vertex to an inside one,
//!    the diagonal goes through the cut point on that long edge (the shorter diagonal for
//!    every admissible cut position); on a face whose long edge joins the two inside
//!    vertices, through the inside vertex of even lattice parity (the *parity rule*). With
//!    these rules no prism is twisted, so no Steiner point is ever needed.
//!
//! With `α_long = 0.24999`, `α_short = 0.41189` the paper proves every dihedral angle of
//! the output lies in [10.7784°, 164.7620°] for any smooth enough surface, given the surface
//! is sampled finely enough relative to its curvature.

use std::collections::HashMap;

use nalgebra::Point3;
use rayon::prelude::*;

use crate::bcc::Bcc;
use crate::stencil::{Cutter, Out, STEINER, Sign, fill_negative};

/// The paper's warping threshold on long edges.
pub const ALPHA_LONG: f64 = 0.24999;
/// The paper's warping threshold on short edges.
pub const ALPHA_SHORT: f64 = 0.41189;
/// The paper's proven lower bound on dihedral angles for these thresholds, degrees.
pub const MIN_DIHEDRAL_BOUND_DEG: f64 = 10.7784;
/// The paper's proven upper bound on dihedral angles, degrees.
pub const MAX_DIHEDRAL_BOUND_DEG: f64 = 164.7620;

/// Which lattice tetrahedra to fill.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fill {
    /// All (a volume mesh).
    All,
    /// Only those with a vertex on or outside the surface: a shell that holds every
    /// boundary face (used to extract the surface alone).
    Shell,
}

/// A stuffed tetrahedral mesh before conversion to a [`bs_mesh::Mesh`].
#[derive(Debug, Clone, Default)]
pub struct Stuffed {
    /// Node positions (world, mm).
    pub nodes: Vec<Point3<f64>>,
    /// Positively oriented tetrahedra.
    pub tets: Vec<[u32; 4]>,
    /// Whether a node lies on the surface (a cut point or a warped vertex).
    pub on_surface: Vec<bool>,
    /// Lattice vertex id of each node (`u32::MAX` for cut points).
    pub lattice_id: Vec<u32>,
    /// The lattice used.
    pub lattice: Option<Bcc>,
    /// How many lattice vertices were warped onto the surface.
    pub warped: usize,
}

/// Root of `f` on the segment `a`–`b` where `fa = f(a)`, `fb = f(b)` have opposite signs.
pub fn root<F: Fn(&Point3<f64>) -> f64>(
    f: &F,
    a: Point3<f64>,
    b: Point3<f64>,
    fa: f64,
    fb: f64,
) -> Point3<f64> {
    let (mut t0, mut t1, mut f0, mut f1) = (0.0, 1.0, fa, fb);
    let mut t = 0.5;
    let mut side = 0i8;
    for _ in 0..30 {
        t = (t0 * f1 - t1 * f0) / (f1 - f0);
        if !t.is_finite() {
            t = 0.5 * (t0 + t1);
        }
        let ft = f(&(a + (b - a) * t));
        if ft == 0.0 || (t1 - t0) < 1e-9 {
            break;
        }
        if (ft < 0.0) == (f0 < 0.0) {
            t0 = t;
            f0 = ft;
            if side == -1 {
                f1 *= 0.5;
            }
            side = -1;
        } else {
            t1 = t;
            f1 = ft;
            if side == 1 {
                f0 *= 0.5;
            }
            side = 1;
        }
        if ft.abs() < 1e-9 {
            break;
        }
    }
    a + (b - a) * t.clamp(0.0, 1.0)
}

struct LatticeCutter<'a> {
    bcc: &'a Bcc,
    pos: &'a [Point3<f64>],
    cuts: &'a HashMap<(u32, u32), u32>,
}

impl Cutter for LatticeCutter<'_> {
    #[inline]
    fn cut(&self, a: u32, b: u32) -> u32 {
        self.cuts[&(a.min(b), a.max(b))]
    }
    #[inline]
    fn face_diagonal(&self, na: u32, nb: u32, p: u32) -> bool {
        lattice_face_diagonal(self.bcc, na, nb, p)
    }
    fn free_diagonal(&self, q: [u32; 4]) -> bool {
        let d02 = (self.pos[q[0] as usize] - self.pos[q[2] as usize]).norm_squared();
        let d13 = (self.pos[q[1] as usize] - self.pos[q[3] as usize]).norm_squared();
        d02 <= d13
    }
    #[inline]
    fn pos(&self, v: u32) -> Point3<f64> {
        self.pos[v as usize]
    }
}

/// The stuffing rule for the quadrilateral of lattice face (`na`, `nb`, `p`) (inside `na`,
/// `nb`): see the module documentation. True for the diagonal `na`–cut(`nb`, `p`).
pub fn lattice_face_diagonal(bcc: &Bcc, na: u32, nb: u32, p: u32) -> bool {
    if bcc.is_long(na, p) {
        false
    } else if bcc.is_long(nb, p) {
        true
    } else {
        bcc.is_even(na)
    }
}

/// Stuffs `{f < 0}` inside the box `lo..hi` (where `f` must be positive near the box's
/// faces) with a BCC lattice of spacing `h`.
pub fn stuff<F: Fn(&Point3<f64>) -> f64 + Sync>(
    f: &F,
    lo: Point3<f64>,
    hi: Point3<f64>,
    h: f64,
    fill: Fill,
) -> Stuffed {
    let bcc = Bcc::covering(lo, hi, h, 1);
    let nv = bcc.vertex_count();
    let mut pos: Vec<Point3<f64>> =
        (0..nv as u32).into_par_iter().map(|v| bcc.position(v)).collect();
    let mut val: Vec<f64> = pos.par_iter().map(f).collect();

    // Cut points on sign-changing edges.
    let cuts: Vec<(u32, u32, Point3<f64>)> = (0..nv as u32)
        .into_par_iter()
        .fold(Vec::new, |mut acc, v| {
            let fv = val[v as usize];
            let (nb, k) = bcc.forward_edges(v);
            for &w in &nb[..k] {
                let fw = val[w as usize];
                if (fv < 0.0 && fw > 0.0) || (fv > 0.0 && fw < 0.0) {
                    acc.push((v, w, root(f, pos[v as usize], pos[w as usize], fv, fw)));
                }
            }
            acc
        })
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });

    // Warping.
    let mut violations: Vec<(u32, f64, u32)> = Vec::new();
    let mut incident: Vec<(u32, u32)> = Vec::with_capacity(2 * cuts.len());
    for (ci, &(v, w, c)) in cuts.iter().enumerate() {
        let (pv, pw) = (pos[v as usize], pos[w as usize]);
        let len = (pw - pv).norm();
        let alpha = if bcc.is_long(v, w) { ALPHA_LONG } else { ALPHA_SHORT };
        let (dv, dw) = ((c - pv).norm(), (c - pw).norm());
        if dv < alpha * len {
            violations.push((v, dv, ci as u32));
        }
        if dw < alpha * len {
            violations.push((w, dw, ci as u32));
        }
        incident.push((v, ci as u32));
        incident.push((w, ci as u32));
    }
    violations.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
    incident.sort_unstable();
    let mut alive = vec![true; cuts.len()];
    let mut warped = 0usize;
    let mut k = 0;
    while k < violations.len() {
        let v = violations[k].0;
        let mut end = k;
        while end < violations.len() && violations[end].0 == v {
            end += 1;
        }
        if let Some(&(_, _, ci)) = violations[k..end].iter().find(|x| alive[x.2 as usize]) {
            pos[v as usize] = cuts[ci as usize].2;
            val[v as usize] = 0.0;
            warped += 1;
            let start = incident.partition_point(|x| x.0 < v);
            for &(u, cj) in &incident[start..] {
                if u != v {
                    break;
                }
                alive[cj as usize] = false;
            }
        }
        k = end;
    }

    // Surviving cut points become nodes after the lattice vertices.
    let mut map = HashMap::with_capacity(cuts.len());
    for (ci, &(v, w, c)) in cuts.iter().enumerate() {
        if alive[ci] {
            map.insert((v.min(w), v.max(w)), pos.len() as u32);
            pos.push(c);
        }
    }
    let cutter = LatticeCutter { bcc: &bcc, pos: &pos, cuts: &map };

    // Stencils, in parallel over cubes.
    let outs: Vec<Out> = (0..bcc.cube_count())
        .into_par_iter()
        .fold(Out::default, |mut out, c| {
            let mut tets = Vec::with_capacity(12);
            bcc.cube_tets(bcc.cube(c), &mut tets);
            for t in tets {
                let s = t.map(|v| Sign::of(val[v as usize]));
                let neg = s.iter().filter(|&&x| x == Sign::Neg).count();
                if neg == 0 {
                    // Outside, or all four vertices on the surface (a possibly flat
                    // tetrahedron the quality bound does not cover): not part of the mesh.
                    continue;
                }
                if fill == Fill::Shell && neg == 4 {
                    continue;
                }
                fill_negative(t, s, None, &cutter, &mut out);
            }
            out
        })
        .collect();

    let cut_end = pos.len();
    // Merge (Steiner points, never produced by the lattice rules, are appended).
    let mut tets = Vec::with_capacity(outs.iter().map(|o| o.tets.len()).sum());
    for o in outs {
        let base = pos.len() as u32;
        pos.extend_from_slice(&o.steiner);
        tets.extend(
            o.tets
                .into_iter()
                .map(|t| t.map(|v| if v >= STEINER { base + (v - STEINER) } else { v })),
        );
    }
    let total = pos.len();
    // Compact to the used nodes.
    let mut new_id = vec![u32::MAX; total];
    let mut nodes = Vec::new();
    let mut on_surface = Vec::new();
    let mut lattice_id = Vec::new();
    for t in &mut tets {
        for v in t.iter_mut() {
            let old = *v as usize;
            if new_id[old] == u32::MAX {
                new_id[old] = nodes.len() as u32;
                nodes.push(pos[old]);
                let is_lattice = old < nv;
                on_surface.push(if is_lattice { val[old] == 0.0 } else { old < cut_end });
                lattice_id.push(if is_lattice { old as u32 } else { u32::MAX });
            }
            *v = new_id[old];
        }
    }
    Stuffed { nodes, tets, on_surface, lattice_id, lattice: Some(bcc), warped }
}
