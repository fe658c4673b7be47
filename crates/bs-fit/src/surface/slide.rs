//! The prior on what a scan cannot see: the exposed surface sliding along itself.
//!
//! A scan says where the surface is, not where each of its material points went. On a
//! brain held only at its stem and free to slide on a frictionless skull, that sliding is
//! nearly free for the model too, and the data's pull on a partly scanned, sloped or noisy
//! window drives it: the whole brain turns by millimetres inside the skull (on the study of
//! docs/fit.md a quarter-scanned window at σ = 2 mm slid 3.3 mm and the fit was worse than
//! no correction). Brain shift at a craniotomy is a sinking of the exposed surface into the
//! window (gravity, drained fluid; the head is positioned with the window up), so the prior
//! resists the patch's displacement across one direction `g` (by default the patch's mean
//! inward normal), as weakly as the tissue resists a displacement of the window's size:
//!
//! `E_s = ½ κ_s ∫_patch |(I − g gᵀ) u|² dA`,   `κ_s = 4π μ / √A`,
//!
//! `A` the patch's area, `μ` the shear modulus under it (an incompressible half-space resists
//! a surface displacement of wavelength `λ` with about `4π μ / λ` per area). Motion along
//! `g` is free; the data and the elasticity decide everything they determine, and the prior
//! picks among what they leave free. Two springs per patch node, lumped by a third of the
//! area of its faces, in the reference configuration.

use bs_dr::{Spring, Springs};
use bs_mesh::{Point3, Vector3};

/// The sliding prior of a scanned patch: the direction its surface sinks along, and the
/// stiffness per area resisting displacement across it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slide {
    /// The unit direction along which the patch moves freely.
    pub direction: Vector3<f64>,
    /// Stiffness per area resisting displacement across `direction` (Pa per length unit).
    pub stiffness: f64,
}

/// `κ_s = 4π μ / √A`: the stiffness per area with which tissue of shear modulus `mu`
/// resists a surface displacement of the patch's size (`area` its area).
pub fn slide_stiffness(mu: f64, area: f64) -> f64 {
    4.0 * std::f64::consts::PI * mu / area.max(f64::MIN_POSITIVE).sqrt()
}

/// The area-weighted mean inward normal of outward-oriented triangles (`None` when their
/// normals cancel: a closed surface has no window direction).
pub fn inward_normal(vertices: &[Point3<f64>], triangles: &[[u32; 3]]) -> Option<Vector3<f64>> {
    let sum: Vector3<f64> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|k| vertices[k as usize]);
            (b - a).cross(&(c - a))
        })
        .sum();
    let scale: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|k| vertices[k as usize]);
            (b - a).cross(&(c - a)).norm()
        })
        .sum();
    (sum.norm() > 1e-6 * scale).then(|| -sum.normalize())
}

/// A third of the area of each vertex's triangles.
pub(crate) fn lumped_areas(vertices: &[Point3<f64>], triangles: &[[u32; 3]]) -> Vec<f64> {
    let mut area = vec![0.0; vertices.len()];
    for t in triangles {
        let [a, b, c] = t.map(|k| vertices[k as usize]);
        let third = (b - a).cross(&(c - a)).norm() / 6.0;
        for &k in t {
            area[k as usize] += third;
        }
    }
    area
}

/// Pushes the prior's springs: for node `nodes[k]` at reference `reference[k]` with lumped
/// area `areas[k]`, two springs across `slide.direction` holding it at its reference
/// position there.
pub(crate) fn push_springs(
    slide: &Slide,
    nodes: &[usize],
    reference: &[Point3<f64>],
    areas: &[f64],
    springs: &mut Springs,
) {
    let g = slide.direction;
    let helper = if g.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let e1 = g.cross(&helper).normalize();
    let e2 = g.cross(&e1);
    for ((&a, x), area) in nodes.iter().zip(reference).zip(areas) {
        for e in [e1, e2] {
            springs.push(Spring {
                nodes: [a, 0, 0, 0],
                weights: [1.0, 0.0, 0.0, 0.0],
                direction: e,
                target: e.dot(&x.coords),
                stiffness: slide.stiffness * area,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat 4 × 4 patch of unit cells in z = 0, outward +z.
    fn square() -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let p = (0..25).map(|k| Point3::new((k % 5) as f64, (k / 5) as f64, 0.0)).collect();
        let mut t = Vec::new();
        for j in 0..4u32 {
            for i in 0..4u32 {
                let a = 5 * j + i;
                t.push([a, a + 1, a + 6]);
                t.push([a, a + 6, a + 5]);
            }
        }
        (p, t)
    }

    #[test]
    fn a_window_sinks_along_its_inward_normal_and_a_closed_surface_has_none() {
        let (p, t) = square();
        assert_eq!(inward_normal(&p, &t), Some(-Vector3::z()));
        // A tetrahedron's outward faces cancel.
        let v = [Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)];
        let v = [v[0], v[1], v[2], Point3::new(0.0, 0.0, 1.0)];
        let faces = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        assert_eq!(inward_normal(&v, &faces), None);
    }

    /// The springs' energy is `½ κ_s Σ_a A_a |(I − g gᵀ) u_a|²` with the lumped areas of a
    /// unit grid (a corner node: ⅙ or ⅓, an edge node ½, an interior node 1), zero for any
    /// motion along `g`.
    #[test]
    fn the_prior_resists_only_displacement_across_the_sag_direction() {
        let (p, t) = square();
        let areas = lumped_areas(&p, &t);
        let expected = |k: usize| {
            let (i, j) = (k % 5, k / 5);
            let edge_i = i == 0 || i == 4;
            let edge_j = j == 0 || j == 4;
            match (edge_i, edge_j) {
                (true, true) if (i == 0) == (j == 0) => 1.0 / 3.0,
                (true, true) => 1.0 / 6.0,
                (true, false) | (false, true) => 0.5,
                _ => 1.0,
            }
        };
        for (k, a) in areas.iter().enumerate() {
            assert!((a - expected(k)).abs() < 1e-12, "node {k}: {a}");
        }
        let g = Vector3::new(0.3, -0.2, -1.0).normalize();
        let slide = Slide { direction: g, stiffness: 7.0 };
        let nodes: Vec<usize> = (0..25).collect();
        let mut springs = Springs::new();
        push_springs(&slide, &nodes, &p, &areas, &mut springs);
        assert_eq!(springs.len(), 50);
        let mut rng = bs_mesh::rng::SplitMix64::new(3);
        let u: Vec<Vector3<f64>> =
            (0..25).map(|_| Vector3::new(rng.normal(), rng.normal(), rng.normal())).collect();
        let exact: f64 = u
            .iter()
            .zip(&areas)
            .map(|(d, a)| 0.5 * 7.0 * a * (d - g * g.dot(d)).norm_squared())
            .sum();
        let energy = springs.energy(&p, &u);
        assert!((energy - exact).abs() < 1e-12 * exact, "{energy} vs {exact}");
        let along: Vec<Vector3<f64>> = u.iter().map(|d| g * d.x).collect();
        assert!(springs.energy(&p, &along) < 1e-24);
    }

    #[test]
    fn the_stiffness_is_the_tissues_at_the_windows_size() {
        // μ = 1 kPa over a 30 mm × 30 mm window: 4π · 1000 / 30 Pa/mm.
        let k = slide_stiffness(1000.0, 900.0);
        assert!((k - 4.0 * std::f64::consts::PI * 1000.0 / 30.0).abs() < 1e-9, "{k}");
    }
}
