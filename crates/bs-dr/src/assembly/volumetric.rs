//! The T4ANP nodal volumetric term of `K₀` (of the sibling module `stiffness`) moved to another
//! configuration in place: the mixed form of the nearly incompressible split rebuilds it at
//! every linearisation point, so the pattern's index maps and the moved tetrahedra live in a
//! caller-owned [`VolumetricScratch`].

use bs_mesh::{Point3, Vector3};
use rayon::prelude::*;

use super::elements::Elements;
use crate::element::Tet;
use crate::linalg::sparse::{RankOneSum, split_rows};

/// Caller-owned buffers of [`volumetric_at`]: the tetrahedra at the configuration, their
/// volume changes, and two index maps of the term's pattern (made at the first call, kept
/// while the pattern's sizes match).
#[derive(Debug, Default)]
pub struct VolumetricScratch {
    tets: Vec<Tet>,
    dj: Vec<f64>,
    /// Per averaging slot (in `Elements::anp_slots` order) and corner: the entry of `C` the
    /// corner's gradient adds to ([`NONE`] when the node is not in the term's row).
    entry: Vec<u32>,
    /// Per entry of `Cᵀ`: the entry of `C` that holds the same vector.
    source: Vec<u32>,
}

/// No entry of `C`.
const NONE: u32 = u32::MAX;

/// The T4ANP nodal volumetric term of `K₀` on the configuration `x` alone, written into `c` (a term
/// built by `linear_stiffness` of the same elements: the pattern is kept, the weights and
/// values are those at `x`); returns the 99th percentile of `|J − 1|` over the tetrahedra
/// whose material's `κ/μ` exceeds `above` (0 without any; `None`, `c` untouched, without
/// T4ANP tetrahedra, with hexahedra, or with a tetrahedron inverted or flat at `x`).
pub(crate) fn volumetric_at(
    elements: &Elements,
    x: &[Point3<f64>],
    c: &mut RankOneSum,
    above: f64,
    scratch: &mut VolumetricScratch,
) -> Option<f64> {
    if !elements.anp() || !elements.hexes.is_empty() {
        return None;
    }
    let mut tets = std::mem::take(&mut scratch.tets);
    let moved = move_tets(elements, x, &mut tets);
    let p99 = moved.then(|| {
        let p99 = percentile_99(elements, &tets, above, &mut scratch.dj);
        fill_moved(elements, &tets, c, scratch);
        p99
    });
    scratch.tets = tets;
    p99
}

/// The T4ANP nodal volumetric term of the tetrahedra `tets` (those of `elements` on another
/// configuration: their gradients and volumes there) written into `c`, a term built by
/// `linear_stiffness` of the same elements.
pub(crate) fn fill_moved(
    elements: &Elements,
    tets: &[Tet],
    c: &mut RankOneSum,
    scratch: &mut VolumetricScratch,
) {
    if scratch.entry.len() != 4 * elements.anp_slots.len() || scratch.source.len() != c.t_val.len()
    {
        scratch.entry = entries(elements, c);
        scratch.source = sources(c);
    }
    fill_rows(elements, tets, &scratch.entry, c);
    let RankOneSum { c_val, t_val, .. } = c;
    t_val.par_iter_mut().zip(scratch.source.par_iter()).with_min_len(1024).for_each(|(v, &s)| {
        *v = c_val[s as usize];
    });
}

/// The tetrahedra with their gradients and volumes at `x` written into `tets`; `false` when
/// one is inverted or flat there.
pub(super) fn move_tets(elements: &Elements, x: &[Point3<f64>], tets: &mut Vec<Tet>) -> bool {
    tets.clear();
    tets.extend_from_slice(&elements.tets);
    tets.par_iter_mut().with_min_len(256).all(|t| {
        let corners = t.nodes.map(|a| x[a as usize]);
        Tet::new(t.nodes, t.mat, &corners)
            .map(|d| {
                t.vol = d.vol;
                t.g = d.g;
            })
            .is_ok()
    })
}

/// The 99th percentile of `|J − 1|` over the tetrahedra of materials with `κ/μ > above`
/// (0 without any).
fn percentile_99(elements: &Elements, tets: &[Tet], above: f64, dj: &mut Vec<f64>) -> f64 {
    let stiff = |mat: u32| {
        let el = elements.solids[mat as usize].material.elastic();
        el.kappa > above * el.mu
    };
    dj.clear();
    dj.extend(
        tets.iter()
            .zip(&elements.tets)
            .filter(|(_, b)| stiff(b.mat))
            .map(|(a, b)| (a.vol / b.vol - 1.0).abs()),
    );
    if dj.is_empty() {
        return 0.0;
    }
    let k = dj.len() / 100;
    *dj.select_nth_unstable_by(k, |a, b| b.total_cmp(a)).1
}

/// The rows of `C` and the weights at the moved tetrahedra: `c_n = Σ V_e ∇J_e / V_n`,
/// `w_n = V_n κ̄_n / 4`.
fn fill_rows(elements: &Elements, tets: &[Tet], entry: &[u32], c: &mut RankOneSum) {
    let RankOneSum { weight, c_ptr, c_val, .. } = c;
    c_val.par_iter_mut().with_min_len(1024).for_each(|v| *v = Vector3::zeros());
    // Each term writes only its own row's entries: split the values by rows.
    let c_ptr = &*c_ptr;
    let rows = split_rows(c_ptr, c_val);
    rows.into_par_iter().zip(weight.par_iter_mut()).enumerate().with_min_len(128).for_each(
        |(r, (vals, w))| {
            let lo = c_ptr[r] as usize;
            let (mut vol, mut vk) = (0.0, 0.0);
            let first = elements.anp_ptr[r] as usize;
            for (k, &s) in elements.anp_slots(r).iter().enumerate() {
                let t = &tets[s as usize / 4];
                vol += t.vol;
                vk += t.vol * elements.solids[t.mat as usize].material.elastic().kappa;
                for b in 0..4 {
                    let e = entry[4 * (first + k) + b];
                    if e != NONE {
                        vals[e as usize - lo] += Vector3::from(t.g[b]) * t.vol;
                    }
                }
            }
            if vol > 0.0 {
                vals.iter_mut().for_each(|v| *v /= vol);
            }
            *w = if vol > 0.0 { vk / 4.0 } else { 0.0 };
        },
    );
}

/// Per averaging slot and corner, the entry of `C` in the slot's term row holding the
/// corner's node.
fn entries(elements: &Elements, c: &RankOneSum) -> Vec<u32> {
    let mut entry = vec![NONE; 4 * elements.anp_slots.len()];
    entry.par_chunks_mut(4).enumerate().with_min_len(256).for_each(|(k, out)| {
        // The term `r` whose slot range holds `k`.
        let r = elements.anp_ptr.partition_point(|&p| p as usize <= k) - 1;
        let (lo, hi) = (c.c_ptr[r] as usize, c.c_ptr[r + 1] as usize);
        let t = &elements.tets[elements.anp_slots[k] as usize / 4];
        for (o, node) in out.iter_mut().zip(t.nodes) {
            if let Ok(i) = c.c_col[lo..hi].binary_search(&node) {
                *o = (lo + i) as u32;
            }
        }
    });
    entry
}

/// Per entry of `Cᵀ` (node `n`, term `t`), the entry of row `t` of `C` at column `n`.
fn sources(c: &RankOneSum) -> Vec<u32> {
    let nodes = c.t_ptr.len() - 1;
    let mut source = vec![0u32; c.t_col.len()];
    for n in 0..nodes {
        for k in c.t_ptr[n] as usize..c.t_ptr[n + 1] as usize {
            let t = c.t_col[k] as usize;
            let (lo, hi) = (c.c_ptr[t] as usize, c.c_ptr[t + 1] as usize);
            let i = c.c_col[lo..hi].binary_search(&(n as u32)).expect("Cᵀ entry in C");
            source[k] = (lo + i) as u32;
        }
    }
    source
}

#[cfg(test)]
mod tests {
    use bs_material::Material;
    use bs_mesh::structured::box_mesh;
    use bs_mesh::{Point3, Vector3};

    use super::VolumetricScratch;
    use crate::{Model, ModelOptions, Solid, TetFormulation};

    #[test]
    fn the_volumetric_term_moved_in_place_is_the_one_built_anew() {
        let mesh = box_mesh(4, 1.0, true);
        let solid =
            Solid { material: Material::neo_hookean(3000.0, 0.499).unwrap(), density: 1000.0 };
        let opts = ModelOptions { tet: TetFormulation::T4Anp, hourglass: 0.1 };
        let model = Model::uniform(&mesh, solid, opts).unwrap();
        // A smooth deformation that changes volumes by up to about 10 %.
        let x: Vec<Point3<f64>> = model
            .reference()
            .iter()
            .map(|p| p + Vector3::new(0.1 * p.x * p.y, 0.05 * (3.0 * p.z).sin(), -0.08 * p.x))
            .collect();
        let mut c = model.linear_stiffness().nodal.unwrap();
        let mut scratch = VolumetricScratch::default();
        // First on another configuration, so that the second call reuses the index maps.
        let half: Vec<Point3<f64>> =
            model.reference().iter().zip(&x).map(|(p, q)| p + (q - p) * 0.5).collect();
        model.volumetric_at(&half, &mut c, 100.0, &mut scratch).unwrap();
        let dj = model.volumetric_at(&x, &mut c, 100.0, &mut scratch).unwrap();
        assert_eq!(model.volumetric_at(&x, &mut c, 1e9, &mut scratch), Some(0.0));
        let mut moved_mesh = mesh.clone();
        moved_mesh.nodes.clone_from(&x);
        let moved = Model::uniform(&moved_mesh, solid, opts).unwrap();
        let fresh = moved.linear_stiffness().nodal.unwrap();
        assert_eq!((&c.c_col, &c.t_col), (&fresh.c_col, &fresh.t_col));
        let close = |a: &[Vector3<f64>], b: &[Vector3<f64>]| {
            a.iter().zip(b).all(|(u, v)| (u - v).amax() <= 1e-12 * (1.0 + v.amax()))
        };
        assert!(close(&c.c_val, &fresh.c_val) && close(&c.t_val, &fresh.t_val));
        assert!(c.weight.iter().zip(&fresh.weight).all(|(a, b)| (a - b).abs() <= 1e-12 * b));
        // The percentile against a direct sort of the tetrahedra's volume changes.
        let elements = &model.elements;
        let mut all: Vec<f64> = elements
            .tets
            .iter()
            .map(|t| {
                let p = t.nodes.map(|a| x[a as usize]);
                let v = (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0])).abs() / 6.0;
                (v / t.vol - 1.0).abs()
            })
            .collect();
        all.sort_by(|a, b| b.total_cmp(a));
        assert!((dj - all[all.len() / 100]).abs() <= 1e-12, "{dj} vs {}", all[all.len() / 100]);
        assert!(dj > 0.01);
    }
}
