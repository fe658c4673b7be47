//! Regions with their own material (ventricles, tumour...) as conforming element sets.
//!
//! The union of the brain is stuffed first ([`crate::stuffing`]); then each region's
//! level set `φ_r = 1/2` cuts the tetrahedra in turn, with the same machinery kept on
//! *both* sides:
//!
//! 1. cut points on every mesh edge whose ends have strictly opposite signs;
//! 2. interior nodes closer to a cut point than α × edge length (the stuffing thresholds,
//!    by lattice edge type) snap onto it — nodes on the outer surface or on an earlier
//!    region's interface never move, so the domain and earlier interfaces stay put;
//! 3. every cut tetrahedron is split by the stencils into its negative part (the region)
//!    and its positive part (what it was), with quadrilaterals split by the lattice rules
//!    on lattice faces and by the minimum-id rule elsewhere (both functions of the face
//!    only), and the isosurface quadrilateral of the two–two case chosen once for both
//!    sides.
//!
//! Every element is therefore on one side of every region surface: its nodes' signs never
//! mix − and + (checked in the tests). Away from the outer surface the tetrahedra cut are
//! lattice tetrahedra and the cut is isosurface stuffing with both sides kept; near it the
//! quality bound of the paper does not apply (the report shows the measured angles).

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::bcc::Bcc;
use crate::implicit::SampledField;
use crate::stencil::{Cutter, Out, STEINER, Sign, fill_negative};
use crate::stuffing::{ALPHA_LONG, ALPHA_SHORT, Stuffed, lattice_face_diagonal, root};

struct MeshCutter<'a> {
    bcc: &'a Bcc,
    pos: &'a [Point3<f64>],
    lattice: &'a [u32],
    cuts: &'a HashMap<(u32, u32), u32>,
}

impl Cutter for MeshCutter<'_> {
    fn cut(&self, a: u32, b: u32) -> u32 {
        self.cuts[&(a.min(b), a.max(b))]
    }
    fn face_diagonal(&self, na: u32, nb: u32, p: u32) -> bool {
        let l = |v: u32| self.lattice.get(v as usize).copied().unwrap_or(u32::MAX);
        let (la, lb, lp) = (l(na), l(nb), l(p));
        if la != u32::MAX && lb != u32::MAX && lp != u32::MAX {
            return lattice_face_diagonal(self.bcc, la, lb, lp);
        }
        // Minimum-id rule: the diagonal through the smallest id of the quad.
        let (ca, cb) = (self.cut(na, p), self.cut(nb, p));
        na.min(cb) < nb.min(ca)
    }
    fn free_diagonal(&self, q: [u32; 4]) -> bool {
        let d02 = (self.pos[q[0] as usize] - self.pos[q[2] as usize]).norm_squared();
        let d13 = (self.pos[q[1] as usize] - self.pos[q[3] as usize]).norm_squared();
        d02 < d13 || (d02 == d13 && q[0].min(q[2]) < q[1].min(q[3]))
    }
    fn pos(&self, v: u32) -> Point3<f64> {
        self.pos[v as usize]
    }
}

/// Cuts the stuffed brain by each region field in turn (negative inside the region).
/// Returns the region of every tetrahedron: 0 for the rest of the brain, `r + 1` for
/// region `r`. Nodes on the outer surface (`s.on_surface`) are never moved.
pub fn split(s: &mut Stuffed, fields: &[SampledField]) -> Vec<u8> {
    let bcc = s.lattice.clone().expect("a stuffed mesh knows its lattice");
    let mut label = vec![0u8; s.tets.len()];
    let mut locked = s.on_surface.clone();
    for (r, field) in fields.iter().enumerate() {
        let region = (r + 1) as u8;
        let mut f: Vec<f64> = s.nodes.par_iter().map(|p| field.eval(p)).collect();
        // 1. Cut edges.
        let mut edges: Vec<(u32, u32)> = s
            .tets
            .par_iter()
            .flat_map_iter(|t| {
                let mut e = Vec::new();
                for i in 0..4 {
                    for j in i + 1..4 {
                        let (a, b) = (t[i], t[j]);
                        let (fa, fb) = (f[a as usize], f[b as usize]);
                        if (fa < 0.0 && fb > 0.0) || (fa > 0.0 && fb < 0.0) {
                            e.push((a.min(b), a.max(b)));
                        }
                    }
                }
                e
            })
            .collect();
        if edges.is_empty() {
            // The region is smaller than the mesh resolution (or absent): label by sign.
            for (t, l) in s.tets.iter().zip(label.iter_mut()) {
                if *l == 0 && t.iter().any(|&v| f[v as usize] < 0.0) {
                    *l = region;
                }
            }
            continue;
        }
        edges.par_sort_unstable();
        edges.dedup();
        let eval = |p: &Point3<f64>| field.eval(p);
        let cut_pos: Vec<Point3<f64>> = edges
            .par_iter()
            .map(|&(a, b)| {
                let (pa, pb) = (s.nodes[a as usize], s.nodes[b as usize]);
                root(&eval, pa, pb, f[a as usize], f[b as usize])
            })
            .collect();
        // 2. Snapping of unlocked nodes.
        let mut violations: Vec<(u32, f64, u32)> = Vec::new();
        let mut incident: Vec<(u32, u32)> = Vec::with_capacity(2 * edges.len());
        for (ci, (&(a, b), c)) in edges.iter().zip(&cut_pos).enumerate() {
            let (pa, pb) = (s.nodes[a as usize], s.nodes[b as usize]);
            let len = (pb - pa).norm();
            let (la, lb) = (s.lattice_id[a as usize], s.lattice_id[b as usize]);
            let alpha = if la != u32::MAX && lb != u32::MAX && !bcc.is_long(la, lb) {
                ALPHA_SHORT
            } else {
                ALPHA_LONG
            };
            for (v, pv) in [(a, pa), (b, pb)] {
                let d = (c - pv).norm();
                if !locked[v as usize] && d < alpha * len {
                    violations.push((v, d, ci as u32));
                }
            }
            incident.push((a, ci as u32));
            incident.push((b, ci as u32));
        }
        violations
            .sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)).then(x.2.cmp(&y.2)));
        incident.sort_unstable();
        let mut alive = vec![true; edges.len()];
        let mut k = 0;
        while k < violations.len() {
            let v = violations[k].0;
            let mut end = k;
            while end < violations.len() && violations[end].0 == v {
                end += 1;
            }
            if let Some(&(_, _, ci)) = violations[k..end].iter().find(|x| alive[x.2 as usize]) {
                s.nodes[v as usize] = cut_pos[ci as usize];
                f[v as usize] = 0.0;
                locked[v as usize] = true;
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
        // 3. Surviving cut points become nodes on the interface.
        let mut cuts = HashMap::new();
        for (ci, &(a, b)) in edges.iter().enumerate() {
            if alive[ci] {
                cuts.insert((a, b), s.nodes.len() as u32);
                s.nodes.push(cut_pos[ci]);
                f.push(0.0);
                locked.push(true);
                s.on_surface.push(false);
                s.lattice_id.push(u32::MAX);
            }
        }
        let cutter = MeshCutter { bcc: &bcc, pos: &s.nodes, lattice: &s.lattice_id, cuts: &cuts };
        let pieces: Vec<(Out, Vec<u8>)> = s
            .tets
            .par_iter()
            .zip(label.par_iter())
            .fold(
                || (Out::default(), Vec::new()),
                |(mut out, mut labels), (t, &l)| {
                    let sg = t.map(|v| Sign::of(f[v as usize]));
                    let neg = sg.contains(&Sign::Neg);
                    let pos = sg.contains(&Sign::Pos);
                    let inside_label = if l == 0 { region } else { l };
                    if !(neg && pos) {
                        let inside = if neg {
                            true
                        } else if pos {
                            false
                        } else {
                            let c =
                                t.iter().map(|&v| cutter.pos(v).coords).sum::<Vector3<f64>>() / 4.0;
                            field.eval(&Point3::from(c)) < 0.0
                        };
                        out.tets.push(*t);
                        labels.push(if inside { inside_label } else { l });
                        return (out, labels);
                    }
                    let flipped = sg.map(Sign::flip);
                    let free = choose_free(*t, sg, &cutter);
                    let before = out.tets.len();
                    fill_negative(*t, sg, free, &cutter, &mut out);
                    labels.extend(std::iter::repeat_n(inside_label, out.tets.len() - before));
                    let before = out.tets.len();
                    fill_negative(*t, flipped, free, &cutter, &mut out);
                    labels.extend(std::iter::repeat_n(l, out.tets.len() - before));
                    (out, labels)
                },
            )
            .collect();
        let mut tets = Vec::with_capacity(s.tets.len() + edges.len() * 4);
        let mut new_label = Vec::with_capacity(tets.capacity());
        for (o, l) in pieces {
            let base = s.nodes.len() as u32;
            for p in &o.steiner {
                s.nodes.push(*p);
                s.on_surface.push(false);
                s.lattice_id.push(u32::MAX);
                locked.push(true);
            }
            tets.extend(
                o.tets
                    .into_iter()
                    .map(|t| t.map(|v| if v >= STEINER { base + (v - STEINER) } else { v })),
            );
            new_label.extend(l);
        }
        s.tets = tets;
        label = new_label;
    }
    label
}

/// One diagonal for the isosurface quad of a two–two tetrahedron that leaves neither
/// side's prism twisted (if possible), or `None` for the other cases.
fn choose_free(t: [u32; 4], s: [Sign; 4], c: &impl Cutter) -> Option<bool> {
    let (q0, pref, q2) = crate::stencil::two_two_diagonals(t, s, c)?;
    let flipped = s.map(Sign::flip);
    let (p0, _, p2) = crate::stencil::two_two_diagonals(t, flipped, c)?;
    let twisted = |x: bool| (q0 == q2 && q0 == x) || (p0 == p2 && p0 == x);
    Some(if twisted(pref) && !twisted(!pref) { !pref } else { pref })
}
