//! The contact seam: a kinematic frictionless floor implemented on the test side (the way
//! bs-contact does for the skull) drives DR to the answer of a symmetry plane.

use bs_dr::{Contact, ContactReport, DrParams, DynamicRelaxation, Loads, NoContact};
use bs_material::Material;
use bs_mesh::{Point3, Vector3};

use crate::common::*;

/// Rigid frictionless floor `z ≥ 0`: nodes below it are moved to their closest point on it.
struct Floor {
    calls: usize,
}

impl Contact for Floor {
    fn enforce(&mut self, positions: &mut [Point3<f64>]) -> ContactReport {
        self.calls += 1;
        let mut report = ContactReport::default();
        for p in positions.iter_mut() {
            if p.z < 0.0 {
                report.nodes_in_contact += 1;
                report.max_penetration = report.max_penetration.max(-p.z);
                p.z = 0.0;
            }
        }
        report
    }
}

#[test]
fn frictionless_floor_acts_as_a_symmetry_plane() {
    // Uniaxial compression with symmetry planes x = 0, y = 0, but the z = 0 plane replaced by
    // contact with a rigid floor: the exact answer is the same homogeneous field
    // u = ((λt−1)x, (λt−1)y, (λz−1)z). Reference λt from the symmetry-plane DR run (which
    // the homogeneous tests check against the closed form to 1e-6).
    let (mesh, model, floor, bottom) = block_on_floor();
    let mut sym = floor.clone();
    for &i in &bottom {
        sym.fix(i, 2).unwrap();
    }
    let dr = DynamicRelaxation::new(DrParams { tolerance: 1e-9, ..Default::default() });
    let reference =
        dr.solve(bs_dr::Problem::new(&model, &sym, &mut NoContact, &mut |_| {})).unwrap();
    let mut contact = Floor { calls: 0 };
    let mut max_in_contact = 0;
    let sol = dr
        .solve(bs_dr::Problem::new(&model, &floor, &mut contact, &mut |p| {
            max_in_contact = max_in_contact.max(p.contact.nodes_in_contact)
        }))
        .unwrap();
    // Called once per step; the 16 bottom nodes are pushed into the floor during loading.
    assert_eq!(contact.calls, sol.report.steps);
    assert_eq!(max_in_contact, 16);
    let diff = max_diff(&sol.displacements, &reference.displacements);
    assert!(diff <= 1e-6 * 0.2, "floor vs symmetry plane: {diff:e}");
    // Prescribed components are exactly their final values.
    for (i, p) in mesh.nodes.iter().enumerate() {
        if (p.z - 1.0).abs() < 1e-12 {
            assert_eq!(sol.displacements[i].z, -0.2);
        }
        if p.x.abs() < 1e-12 {
            assert_eq!(sol.displacements[i].x, 0.0);
        }
    }
    let _ = Vector3::<f64>::zeros();
}

/// Rigid spherical skull of radius `r` centred at the origin; prescribed nodes are not slaves
/// (as in the CLI).
struct SphereSkull {
    radius: f64,
    slave: Vec<bool>,
}

impl Contact for SphereSkull {
    fn enforce(&mut self, positions: &mut [Point3<f64>]) -> ContactReport {
        let mut report = ContactReport::default();
        for (p, &s) in positions.iter_mut().zip(&self.slave) {
            let d = p.coords.norm();
            if s && d > self.radius {
                report.nodes_in_contact += 1;
                report.max_penetration = report.max_penetration.max(d - self.radius);
                *p = Point3::from(p.coords * (self.radius / d));
            }
        }
        report
    }
}

/// A brain-shift-like run on the gmsh sphere fixture (R = 10 mm, T4ANP, ν = 0.45): brain-stem
/// nodes fixed, a "craniotomy" cap pushed in by 1.5 mm, the rest held inside a rigid skull of
/// the same radius by the kinematic contact. Checks: DR converges (no false guard trip with
/// contact active), the skull constraint holds to round-off at every node, the contact was
/// needed (without it the brain bulges through the skull by a sizeable amount), and the
/// prescribed nodes are exact.
#[test]
fn brain_shift_like_run_in_a_spherical_skull() {
    use bs_dr::{Model, ModelOptions, Solid, TetFormulation};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/basic");
    let mesh = bs_mesh::io::read_mesh(&dir.join("sphere.msh")).unwrap();
    let material = Material::neo_hookean(3000.0, 0.45).unwrap();
    let model = Model::uniform(
        &mesh,
        Solid { material, density: 1000.0 },
        ModelOptions { tet: TetFormulation::T4Anp, ..Default::default() },
    )
    .unwrap();
    let radius = mesh.nodes.iter().fold(0.0f64, |m, p| m.max(p.coords.norm()));
    assert!((radius - 10.0).abs() < 1e-6);
    let mut loads = Loads::new(mesh.nodes.len());
    let mut slave = vec![true; mesh.nodes.len()];
    let (mut cap, mut stem) = (0, 0);
    for (i, p) in mesh.nodes.iter().enumerate() {
        let on_surface = p.coords.norm() > radius - 1e-6;
        if p.z < -8.5 {
            loads.fix_node(i).unwrap();
            slave[i] = false;
            stem += 1;
        } else if on_surface && p.z > 8.0 {
            loads.prescribe_node(i, Vector3::new(0.0, 0.0, -1.5)).unwrap();
            slave[i] = false;
            cap += 1;
        }
    }
    assert!(cap >= 5 && stem >= 5, "cap {cap}, stem {stem}");
    let dr = DynamicRelaxation::new(DrParams { tolerance: 1e-6, ..Default::default() });
    let free = dr.solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
    let bulge = free
        .displacements
        .iter()
        .zip(&mesh.nodes)
        .fold(0.0f64, |m, (u, x)| m.max((x + u).coords.norm() - radius));
    // Pushing the cap in makes the unconstrained ball bulge sideways through the skull.
    assert!(bulge > 0.05, "bulge without contact {bulge}");

    let mut skull = SphereSkull { radius, slave };
    let mut in_contact = 0;
    let sol = dr
        .solve(bs_dr::Problem::new(&model, &loads, &mut skull, &mut |p| {
            in_contact = p.contact.nodes_in_contact
        }))
        .unwrap();
    assert!(in_contact > 0, "contact inactive at convergence");
    for (i, (u, x)) in sol.displacements.iter().zip(&mesh.nodes).enumerate() {
        let r = (x + u).coords.norm();
        assert!(r <= radius * (1.0 + 1e-12), "node {i} outside the skull: r = {r}");
        if loads.is_node_constrained(i) {
            for c in 0..3 {
                assert_eq!(u[c], loads.value(i, c));
            }
        }
    }
    // The contact answer differs from the free one by about the bulge it removed.
    let diff = max_diff(&sol.displacements, &free.displacements);
    assert!(diff > 0.5 * bulge, "contact changed the answer by only {diff}");
}
