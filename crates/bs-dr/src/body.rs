//! Body forces: the consistent nodal loads `f_a = ∫ N_a b dV` of a force `b` per unit
//! reference volume (gravity `ρ g`), with an optional fluid below a plane that buoys the
//! tissue there (`b = (ρ − ρ_f) g`: cerebrospinal fluid around a brain, drained above its
//! level).
//!
//! The load is dead (Total Lagrangian: per unit *reference* volume, the plane taken in the
//! reference configuration). Tetrahedra (T4 and T4ANP share their linear shape functions)
//! are integrated exactly: a tetrahedron the plane cuts is clipped, its submerged part split
//! into tetrahedra, and each contributes its volume times the parent's shape functions at its
//! centroid (exact for a linear integrand). Hexahedra use 2×2×2 Gauss points (exact for a
//! trilinear hexahedron and a constant `b`); a hexahedron the plane cuts is integrated on
//! 8×8×8 sub-cells of 2×2×2 points each, its indicator sampled at the points (an error of
//! the order of the sub-cell's share of the cut, on those elements only).

use bs_mesh::{HEX_REFERENCE, Point3, Vector3};

use crate::model::Model;

/// A body force per unit reference volume, in the model's units (stress per length).
#[derive(Debug, Clone, PartialEq)]
pub struct BodyForce {
    /// The force per unit volume in each solid of the model (`ρ_s g`).
    pub per_solid: Vec<Vector3<f64>>,
    /// A fluid below a plane: its force is added there.
    pub buoyancy: Option<Buoyancy>,
}

/// The buoyancy of a fluid filling the space below a plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Buoyancy {
    /// The force per unit volume added below the plane (`−ρ_f g`).
    pub per_volume: Vector3<f64>,
    /// A point of the plane (the fluid's level).
    pub level: Point3<f64>,
    /// The plane's unit normal pointing into the fluid (along gravity).
    pub down: Vector3<f64>,
}

/// Why a [`BodyForce`] does not fit a model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BodyError {
    /// Not one force per solid.
    #[error(
        "body force: {got} per-solid values for a model of {expected} solids: give one per solid"
    )]
    Solids {
        /// Solids of the model.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A non-finite value, or a fluid plane's normal that is not a unit vector.
    #[error("body force: {0}")]
    Invalid(&'static str),
}

impl BodyForce {
    fn check(&self, solids: usize) -> Result<(), BodyError> {
        if self.per_solid.len() != solids {
            return Err(BodyError::Solids { expected: solids, got: self.per_solid.len() });
        }
        let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
        if !self.per_solid.iter().all(finite) {
            return Err(BodyError::Invalid("a per-solid force is not finite"));
        }
        if let Some(b) = &self.buoyancy {
            if !(finite(&b.per_volume) && b.level.iter().all(|x| x.is_finite())) {
                return Err(BodyError::Invalid("the fluid's force or level is not finite"));
            }
            if (b.down.norm() - 1.0).abs().is_nan() || (b.down.norm() - 1.0).abs() >= 1e-9 {
                return Err(BodyError::Invalid("the fluid plane's normal must be a unit vector"));
            }
        }
        Ok(())
    }
}

impl Model {
    /// The consistent nodal loads of `body` (one per node, the model's force unit), for
    /// `Loads::set_forces`.
    pub fn body_loads(&self, body: &BodyForce) -> Result<Vec<Vector3<f64>>, BodyError> {
        body.check(self.elements.solids.len())?;
        let x = &self.reference;
        let mut f = vec![Vector3::zeros(); x.len()];
        let depth = |p: &Point3<f64>| body.buoyancy.map_or(-1.0, |b| b.down.dot(&(p - b.level)));
        for (_, e) in self.elements.iter() {
            let b = body.per_solid[e.mat];
            let fluid = body.buoyancy.map_or(Vector3::zeros(), |b| b.per_volume);
            if e.nodes.len() == 4 {
                let h: [f64; 4] = std::array::from_fn(|a| depth(&x[e.nodes[a] as usize]));
                let wet = submerged_tet(h);
                for (a, &n) in e.nodes.iter().enumerate() {
                    f[n as usize] += (b * 0.25 + fluid * wet[a]) * e.vol;
                }
            } else {
                let corners: [Point3<f64>; 8] = std::array::from_fn(|a| x[e.nodes[a] as usize]);
                let (full, wet) = hex_integrals(&corners, &depth);
                for (a, &n) in e.nodes.iter().enumerate() {
                    f[n as usize] += b * full[a] + fluid * wet[a];
                }
            }
        }
        Ok(f)
    }
}

/// `∫ N_a dV / V` over the part of a tetrahedron where the signed depth (an affine function
/// with vertex values `h`) is positive; their sum is the submerged volume fraction.
pub fn submerged_tet(h: [f64; 4]) -> [f64; 4] {
    let wet: Vec<usize> = (0..4).filter(|&i| h[i] > 0.0).collect();
    match wet.len() {
        0 => [0.0; 4],
        4 => [0.25; 4],
        3 => {
            let dry = submerged_tet(h.map(|v| -v));
            std::array::from_fn(|a| 0.25 - dry[a])
        }
        1 => {
            let i = wet[0];
            let p: Vec<[f64; 4]> = (0..4).filter(|&j| j != i).map(|j| cut(h, i, j)).collect();
            part(&[unit(i), p[0], p[1], p[2]])
        }
        _ => {
            let dry: Vec<usize> = (0..4).filter(|&j| h[j] <= 0.0).collect();
            let (i0, i1, j0, j1) = (wet[0], wet[1], dry[0], dry[1]);
            let a = [unit(i0), cut(h, i0, j0), cut(h, i0, j1)];
            let b = [unit(i1), cut(h, i1, j0), cut(h, i1, j1)];
            let mut w = [0.0; 4];
            for t in [[a[0], a[1], a[2], b[0]], [a[1], a[2], b[0], b[1]], [a[2], b[0], b[1], b[2]]]
            {
                let pw = part(&t);
                (0..4).for_each(|k| w[k] += pw[k]);
            }
            w
        }
    }
}

/// The barycentric coordinates of vertex `i`.
fn unit(i: usize) -> [f64; 4] {
    std::array::from_fn(|k| if k == i { 1.0 } else { 0.0 })
}

/// Where the edge from vertex `i` (depth > 0) to `j` (depth ≤ 0) crosses depth 0.
fn cut(h: [f64; 4], i: usize, j: usize) -> [f64; 4] {
    let t = h[i] / (h[i] - h[j]);
    std::array::from_fn(|k| (1.0 - t) * unit(i)[k] + t * unit(j)[k])
}

/// `∫ N_a dV / V` over the sub-tetrahedron with barycentric vertices `l`: its volume ratio
/// (the determinant of three edges in the first three coordinates) times its centroid.
fn part(l: &[[f64; 4]; 4]) -> [f64; 4] {
    let e = |m: usize| Vector3::new(l[m][0] - l[0][0], l[m][1] - l[0][1], l[m][2] - l[0][2]);
    let ratio = e(1).dot(&e(2).cross(&e(3))).abs();
    std::array::from_fn(|k| ratio * (l[0][k] + l[1][k] + l[2][k] + l[3][k]) / 4.0)
}

/// The trilinear shape functions and `det ∂X/∂ξ` at `xi`.
fn hex_point(x: &[Point3<f64>; 8], xi: [f64; 3]) -> ([f64; 8], f64, Point3<f64>) {
    let mut n = [0.0; 8];
    let mut jac = nalgebra::Matrix3::zeros();
    let mut p = Vector3::zeros();
    for (a, r) in HEX_REFERENCE.iter().enumerate() {
        let s = [1.0 + r[0] * xi[0], 1.0 + r[1] * xi[1], 1.0 + r[2] * xi[2]];
        n[a] = s[0] * s[1] * s[2] / 8.0;
        let dn = Vector3::new(r[0] * s[1] * s[2], s[0] * r[1] * s[2], s[0] * s[1] * r[2]) / 8.0;
        jac += x[a].coords * dn.transpose();
        p += x[a].coords * n[a];
    }
    (n, jac.determinant(), Point3::from(p))
}

/// `(∫ N_a dV, ∫_{depth > 0} N_a dV)` over a hexahedron (see the module documentation).
fn hex_integrals(
    x: &[Point3<f64>; 8],
    depth: &dyn Fn(&Point3<f64>) -> f64,
) -> ([f64; 8], [f64; 8]) {
    let h: Vec<f64> = x.iter().map(depth).collect();
    let cut = h.iter().any(|&v| v > 0.0) && h.iter().any(|&v| v <= 0.0);
    let cells = if cut { 8 } else { 1 };
    let g = 1.0 / 3f64.sqrt();
    let (mut full, mut wet) = ([0.0; 8], [0.0; 8]);
    let size = 2.0 / cells as f64;
    for c in 0..cells * cells * cells {
        let lo =
            [c % cells, (c / cells) % cells, c / (cells * cells)].map(|i| -1.0 + size * i as f64);
        for q in 0..8 {
            let xi: [f64; 3] =
                std::array::from_fn(|k| lo[k] + size * 0.5 * (1.0 + HEX_REFERENCE[q][k] * g));
            let (n, det, p) = hex_point(x, xi);
            let w = det * (size * 0.5).powi(3);
            let inside = if cut { depth(&p) > 0.0 } else { h[0] > 0.0 };
            for a in 0..8 {
                full[a] += n[a] * w;
                if inside {
                    wet[a] += n[a] * w;
                }
            }
        }
    }
    (full, wet)
}

#[cfg(test)]
mod tests {
    use bs_material::Material;

    use super::*;
    use crate::{ModelOptions, Solid};

    /// Brute force: the mean of `N_a` times the indicator over a fine barycentric lattice.
    fn lattice(h: [f64; 4]) -> [f64; 4] {
        let m = 120;
        let mut w = [0.0; 4];
        let mut count = 0.0;
        for i in 0..m {
            for j in 0..m - i {
                for k in 0..m - i - j {
                    let l = [i, j, k].map(|v| (v as f64 + 0.25) / m as f64);
                    let l = [l[0], l[1], l[2], 1.0 - l[0] - l[1] - l[2]];
                    count += 1.0;
                    if (0..4).map(|a| l[a] * h[a]).sum::<f64>() > 0.0 {
                        (0..4).for_each(|a| w[a] += l[a]);
                    }
                }
            }
        }
        w.map(|v| v / count)
    }

    #[test]
    fn a_clipped_tetrahedron_integrates_its_shape_functions_exactly() {
        // One vertex in: a corner tetrahedron with volume ratio t1 t2 t3.
        let w = submerged_tet([1.0, -1.0, -3.0, -0.25]);
        let (t1, t2, t3) = (0.5, 0.25, 0.8);
        assert!((w.iter().sum::<f64>() - t1 * t2 * t3).abs() < 1e-15);
        for h in [[1.0, -1.0, -3.0, -0.25], [0.7, 0.2, -0.5, -1.1], [0.3, 0.9, 0.4, -0.6]] {
            let (exact, brute) = (submerged_tet(h), lattice(h));
            for a in 0..4 {
                // The lattice's error: its cells on the cut, about 1/m of the volume.
                assert!((exact[a] - brute[a]).abs() < 0.01, "{h:?}: {exact:?} vs {brute:?}");
            }
            // The wet and dry parts make the whole.
            let dry = submerged_tet(h.map(|v| -v));
            (0..4).for_each(|a| assert!((exact[a] + dry[a] - 0.25).abs() < 1e-14));
        }
        // Two vertices on the plane: all but the edge between them is submerged.
        let all = submerged_tet([1.0, 1.0, 0.0, 0.0]);
        all.iter().for_each(|w| assert!((w - 0.25).abs() < 1e-15));
    }

    fn cube(hex: bool) -> Model {
        let mesh = bs_mesh::structured::box_mesh(2, 2.0, !hex);
        let solid = Solid { material: Material::neo_hookean(3000.0, 0.45).unwrap(), density: 1.0 };
        Model::uniform(&mesh, solid, ModelOptions::default()).unwrap()
    }

    #[test]
    fn the_loads_sum_to_the_weight_and_the_fluid_takes_its_share() {
        let g = Vector3::new(0.0, 0.0, -10.0);
        let down = Vector3::new(0.0, 0.0, -1.0);
        for hex in [false, true] {
            let m = cube(hex);
            let dry = BodyForce { per_solid: vec![g], buoyancy: None };
            let f = m.body_loads(&dry).unwrap();
            let total: Vector3<f64> = f.iter().sum();
            assert!((total - g * 8.0).norm() < 1e-12, "{total}");
            // A level at z = 0.7 (cutting the lower layer of elements): the fluid's force
            // is its density times the submerged volume 2 × 2 × 0.7.
            let fluid = Buoyancy { per_volume: -g * 0.4, level: Point3::new(0.0, 0.0, 0.7), down };
            let wet = BodyForce { per_solid: vec![g], buoyancy: Some(fluid) };
            let total: Vector3<f64> = m.body_loads(&wet).unwrap().iter().sum();
            let expected = g * 8.0 - g * 0.4 * 2.8;
            // Hexahedra sample the cut on sub-cells 1/8 of an element high: the submerged
            // height is right within half a sub-cell (1/16), times the area 4 and the fluid's
            // force per volume 4.
            let tol = if hex { 4.0 * 4.0 / 16.0 } else { 1e-12 };
            assert!((total - expected).norm() < tol, "hex {hex}: {total} vs {expected}");
        }
    }

    #[test]
    fn a_trilinear_hexahedron_takes_its_volume_over_eight_on_a_cube() {
        let x: [Point3<f64>; 8] = std::array::from_fn(|a| {
            Point3::from(Vector3::from(HEX_REFERENCE[a]) * 1.5 + Vector3::new(1.0, 2.0, 3.0))
        });
        let (full, _) = hex_integrals(&x, &|_| -1.0);
        full.iter().for_each(|&w| assert!((w - 27.0 / 8.0).abs() < 1e-12));
    }

    #[test]
    fn bad_body_forces_are_refused() {
        let m = cube(false);
        let two = BodyForce { per_solid: vec![Vector3::zeros(); 2], buoyancy: None };
        assert_eq!(m.body_loads(&two), Err(BodyError::Solids { expected: 1, got: 2 }));
        let fluid = Buoyancy {
            per_volume: Vector3::zeros(),
            level: Point3::origin(),
            down: Vector3::new(0.0, 0.0, -2.0),
        };
        let bad = BodyForce { per_solid: vec![Vector3::zeros()], buoyancy: Some(fluid) };
        assert!(matches!(m.body_loads(&bad), Err(BodyError::Invalid(_))));
    }
}
