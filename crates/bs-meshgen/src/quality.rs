//! Dihedral angles and the quality summary of a generated mesh (the radius ratio is
//! bs-mesh's [`tet_radius_ratio`](bs_mesh::quality::tet_radius_ratio)).

use bs_mesh::{ElementKind, Mesh};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// The 6 interior dihedral angles (radians) of a tetrahedron, at edges 01, 02, 03, 12, 13,
/// 23. A degenerate tetrahedron gives angles of 0 or π.
pub fn dihedral_angles(p: &[Point3<f64>; 4]) -> [f64; 6] {
    // The three other vertices of each vertex k (the face opposite k).
    const OPPOSITE: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];
    // Inward normal of the face opposite vertex k (towards k).
    let normal = |k: usize| -> Vector3<f64> {
        let f = OPPOSITE[k];
        let n = (p[f[1]] - p[f[0]]).cross(&(p[f[2]] - p[f[0]]));
        let n = if n.dot(&(p[k] - p[f[0]])) < 0.0 { -n } else { n };
        n.try_normalize(0.0).unwrap_or_else(Vector3::zeros)
    };
    let n = [normal(0), normal(1), normal(2), normal(3)];
    // The edge (i, j) is shared by the faces opposite the other two vertices k, l; the
    // dihedral angle is π minus the angle between their inward normals.
    const OTHERS: [[usize; 2]; 6] = [[2, 3], [1, 3], [1, 2], [0, 3], [0, 2], [0, 1]];
    OTHERS.map(|[k, l]| std::f64::consts::PI - n[k].dot(&n[l]).clamp(-1.0, 1.0).acos())
}

/// Extremes of the element quality of a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QualityStats {
    /// Smallest dihedral angle over the tetrahedra, degrees (NaN without tetrahedra).
    pub min_dihedral_deg: f64,
    /// Largest dihedral angle over the tetrahedra, degrees.
    pub max_dihedral_deg: f64,
    /// Smallest normalised radius ratio `3 r / R` of the tetrahedra (1 = regular).
    pub min_radius_ratio: f64,
    /// Smallest corner scaled Jacobian of the hexahedra (NaN without hexahedra).
    pub min_scaled_jacobian: f64,
    /// Elements with non-positive volume.
    pub inverted: usize,
}

/// Measures every element of `mesh`.
pub fn stats(mesh: &Mesh) -> QualityStats {
    let init = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::INFINITY, 0usize);
    let (mn, mx, rr, sj, inv) = mesh
        .elements
        .par_iter()
        .map(|e| {
            let v = e.nodes();
            match e.kind() {
                ElementKind::Tet4 => {
                    let p = [0, 1, 2, 3].map(|i| mesh.nodes[v[i]]);
                    let a = dihedral_angles(&p);
                    let lo = a.iter().copied().fold(f64::INFINITY, f64::min);
                    let hi = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    let q = bs_mesh::quality::tet_radius_ratio(p);
                    (lo, hi, q, f64::INFINITY, usize::from(q <= 0.0))
                }
                ElementKind::Hex8 => {
                    let p = std::array::from_fn(|i| mesh.nodes[v[i]]);
                    let s = bs_mesh::quality::hex_scaled_jacobian(p);
                    (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, s, usize::from(s <= 0.0))
                }
            }
        })
        .reduce(
            || init,
            |a, b| (a.0.min(b.0), a.1.max(b.1), a.2.min(b.2), a.3.min(b.3), a.4 + b.4),
        );
    let nan_if = |x: f64| if x.is_finite() { x } else { f64::NAN };
    QualityStats {
        min_dihedral_deg: nan_if(mn).to_degrees(),
        max_dihedral_deg: nan_if(mx).to_degrees(),
        min_radius_ratio: nan_if(rr),
        min_scaled_jacobian: nan_if(sj),
        inverted: inv,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_tet_dihedral_is_arccos_one_third() {
        let s = 1.0 / 2f64.sqrt();
        let p = [
            Point3::new(1.0, 0.0, -s),
            Point3::new(-1.0, 0.0, -s),
            Point3::new(0.0, 1.0, s),
            Point3::new(0.0, -1.0, s),
        ];
        for a in dihedral_angles(&p) {
            assert!((a - (1.0f64 / 3.0).acos()).abs() < 1e-12);
        }
        // Corner tet of the unit cube: three 90° angles at the corner's edges, three
        // arccos(1/√3) = 54.7356° at the others.
        let c = [
            Point3::origin(),
            Point3::new(1., 0., 0.),
            Point3::new(0., 1., 0.),
            Point3::new(0., 0., 1.),
        ];
        let a = dihedral_angles(&c);
        for x in &a[..3] {
            assert!((x.to_degrees() - 90.0).abs() < 1e-9);
        }
        for x in &a[3..] {
            assert!((x - (1.0 / 3f64.sqrt()).acos()).abs() < 1e-12);
        }
    }
}
