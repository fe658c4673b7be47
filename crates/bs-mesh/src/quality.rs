//! Element quality measures.
//!
//! * Tetrahedra: the normalised radius ratio `q = 3 r / R` (inradius over circumradius),
//!   1 for the regular tetrahedron, → 0 for slivers, negative for inverted elements.
//! * Hexahedra: the minimum scaled Jacobian over the 8 corners,
//!   `det(e_ξ, e_η, e_ζ) / (|e_ξ| |e_η| |e_ζ|)` with the three edges leaving each corner,
//!   1 for a cube, ≤ 0 for inverted corners.

use nalgebra::{Matrix3, Point3};

use crate::mesh::{HEX_REF, tet_volume};
use crate::{ElementKind, Mesh};

/// Mean element edge length: each tetrahedron counts its 6 edges and each hexahedron its
/// 12, so shared edges count once per element (NaN for a mesh without elements). The
/// length scale of a mesh's resolution, in the mesh's unit.
pub fn mean_edge_length(mesh: &Mesh) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for el in &mesh.elements {
        let v = el.nodes();
        for &[a, b] in el.kind().edges() {
            sum += (mesh.nodes[v[a]] - mesh.nodes[v[b]]).norm();
            n += 1;
        }
    }
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// Normalised radius ratio of a tetrahedron (signed by its orientation).
pub fn tet_radius_ratio(p: [Point3<f64>; 4]) -> f64 {
    let v = tet_volume(&p[0], &p[1], &p[2], &p[3]);
    let (a, b, c) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let area =
        |x: &Point3<f64>, y: &Point3<f64>, z: &Point3<f64>| 0.5 * (y - x).cross(&(z - x)).norm();
    let total_area = area(&p[0], &p[1], &p[2])
        + area(&p[0], &p[1], &p[3])
        + area(&p[0], &p[2], &p[3])
        + area(&p[1], &p[2], &p[3]);
    // Circumradius: |a²(b×c) + b²(c×a) + c²(a×b)| / (12 |V|).
    let num = (a.norm_squared() * b.cross(&c)
        + b.norm_squared() * c.cross(&a)
        + c.norm_squared() * a.cross(&b))
    .norm();
    if v == 0.0 || total_area == 0.0 {
        return 0.0;
    }
    let r_in = 3.0 * v.abs() / total_area;
    let r_circ = num / (12.0 * v.abs());
    (3.0 * r_in / r_circ).copysign(v)
}

/// Minimum scaled Jacobian over the corners of a hexahedron (Abaqus/VTK node order).
pub fn hex_scaled_jacobian(p: [Point3<f64>; 8]) -> f64 {
    let mut worst = f64::INFINITY;
    for (a, ra) in HEX_REF.iter().enumerate() {
        let mut m = Matrix3::zeros();
        let mut lengths = 1.0;
        for axis in 0..3 {
            // The neighbour across `axis`, with the edge oriented along +axis.
            let mut rb = *ra;
            rb[axis] = -rb[axis];
            let b = HEX_REF.iter().position(|r| *r == rb).expect("hex reference corners");
            let e = (p[b] - p[a]) * -ra[axis];
            lengths *= e.norm();
            m.set_column(axis, &e);
        }
        let s = if lengths > 0.0 { m.determinant() / lengths } else { 0.0 };
        worst = worst.min(s);
    }
    worst
}

/// Summary statistics of one quality measure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stats {
    /// Smallest value.
    pub min: f64,
    /// Median value.
    pub median: f64,
    /// Largest value.
    pub max: f64,
    /// Number of elements measured.
    pub count: usize,
}

impl Stats {
    fn of(mut v: Vec<f64>) -> Option<Stats> {
        if v.is_empty() {
            return None;
        }
        v.sort_unstable_by(f64::total_cmp);
        let count = v.len();
        let median =
            if count % 2 == 1 { v[count / 2] } else { 0.5 * (v[count / 2 - 1] + v[count / 2]) };
        Some(Stats { min: v[0], median, max: v[count - 1], count })
    }
}

/// Quality of a whole mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QualitySummary {
    /// Radius ratios of the tetrahedra.
    pub tet_radius_ratio: Option<Stats>,
    /// Minimum corner scaled Jacobians of the hexahedra.
    pub hex_scaled_jacobian: Option<Stats>,
    /// Elements with negative measure (inverted).
    pub inverted: usize,
}

/// Measures every element. Elements with out-of-range nodes are skipped (validate first).
pub fn summary(mesh: &Mesh) -> QualitySummary {
    let (mut tets, mut hexes) = (Vec::new(), Vec::new());
    for el in &mesh.elements {
        let n = el.nodes();
        if n.iter().any(|&i| i >= mesh.nodes.len()) {
            continue;
        }
        match el.kind() {
            ElementKind::Tet4 => {
                tets.push(tet_radius_ratio([0, 1, 2, 3].map(|i| mesh.nodes[n[i]])))
            }
            ElementKind::Hex8 => {
                hexes.push(hex_scaled_jacobian(std::array::from_fn(|i| mesh.nodes[n[i]])))
            }
        }
    }
    let inverted = tets.iter().chain(&hexes).filter(|&&q| q < 0.0).count();
    QualitySummary {
        tet_radius_ratio: Stats::of(tets),
        hex_scaled_jacobian: Stats::of(hexes),
        inverted,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed forms: the unit cube as one hexahedron (12 unit edges) and the unit corner
    /// tetrahedron (3 unit edges, 3 of length √2), together and alone.
    #[test]
    fn mean_edge_length_matches_closed_forms() {
        let c: Vec<Point3<f64>> = (0..8)
            .map(|i| Point3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .collect();
        let hex = crate::Element::hex8([0, 1, 3, 2, 4, 5, 7, 6]);
        let tet = crate::Element::tet4([0, 1, 2, 4]);
        let m = Mesh::new(c.clone(), vec![hex]);
        assert!((mean_edge_length(&m) - 1.0).abs() < 1e-15);
        let m = Mesh::new(c.clone(), vec![tet]);
        let t = (3.0 + 3.0 * 2f64.sqrt()) / 6.0;
        assert!((mean_edge_length(&m) - t).abs() < 1e-15);
        let m = Mesh::new(c, vec![hex, tet]);
        assert!((mean_edge_length(&m) - (12.0 + 6.0 * t) / 18.0).abs() < 1e-15);
        assert!(mean_edge_length(&Mesh::default()).is_nan());
    }

    #[test]
    fn regular_tet_has_ratio_one_and_inverted_is_negative() {
        let s = 1.0 / 2f64.sqrt();
        let p = [
            Point3::new(1.0, 0.0, -s),
            Point3::new(-1.0, 0.0, -s),
            Point3::new(0.0, 1.0, s),
            Point3::new(0.0, -1.0, s),
        ];
        let q = tet_radius_ratio(p);
        approx::assert_relative_eq!(q.abs(), 1.0, epsilon = 1e-14);
        let flipped = [p[0], p[2], p[1], p[3]];
        approx::assert_relative_eq!(tet_radius_ratio(flipped), -q, epsilon = 1e-14);
    }

    #[test]
    fn right_corner_tet_ratio_matches_closed_form() {
        // Corner tet of the unit cube: V = 1/6, total area = 3/2 + sqrt(3)/2,
        // r = 3V/A = 1/(3+sqrt 3), R = sqrt(3)/2  =>  q = 3r/R = 2 sqrt(3)/(3+sqrt 3).
        let p = [
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let expect = 2.0 * 3f64.sqrt() / (3.0 + 3f64.sqrt());
        approx::assert_relative_eq!(tet_radius_ratio(p), expect, epsilon = 1e-14);
    }

    #[test]
    fn cube_has_scaled_jacobian_one_and_sheared_hex_less() {
        let cube: [Point3<f64>; 8] =
            std::array::from_fn(|i| Point3::from(HEX_REF[i].map(|c| 0.5 * (c + 1.0))));
        approx::assert_relative_eq!(hex_scaled_jacobian(cube), 1.0, epsilon = 1e-14);
        // Shear the top face by 1 in x: corner edges (1,0,0), (0,1,0), (1,0,1)/… give
        // scaled Jacobian 1/sqrt(2) at the corners whose vertical edge is sheared.
        let mut sheared = cube;
        for p in &mut sheared[4..] {
            p.x += 1.0;
        }
        approx::assert_relative_eq!(
            hex_scaled_jacobian(sheared),
            1.0 / 2f64.sqrt(),
            epsilon = 1e-14
        );
    }
}
