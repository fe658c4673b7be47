//! The contact seam: a kinematic frictionless floor implemented on the test side (the way
//! bs-contact does for the skull) drives DR to the answer of a symmetry plane.

use bs_dr::{Contact, ContactReport, DrParams, DynamicRelaxation, Loads, NoContact, Solver};
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
    let material = Material::neo_hookean(3000.0, 0.45).unwrap();
    let (mesh, model) = cube_model(Tech::T4, 3, 1.0, 0.2, material);
    let mut sym = Loads::new(mesh.nodes.len());
    let mut floor = Loads::new(mesh.nodes.len());
    for (i, p) in mesh.nodes.iter().enumerate() {
        for loads in [&mut sym, &mut floor] {
            if p.x.abs() < 1e-12 {
                loads.fix(i, 0).unwrap();
            }
            if p.y.abs() < 1e-12 {
                loads.fix(i, 1).unwrap();
            }
            if (p.z - 1.0).abs() < 1e-12 {
                loads.prescribe(i, 2, -0.2).unwrap();
            }
        }
        if p.z.abs() < 1e-12 {
            sym.fix(i, 2).unwrap();
        }
    }
    let dr = DynamicRelaxation::new(DrParams { tolerance: 1e-9, ..Default::default() });
    let reference = dr.solve(&model, &sym, &mut NoContact, &mut |_| {}).unwrap();
    let mut contact = Floor { calls: 0 };
    let mut max_in_contact = 0;
    let sol = dr
        .solve(&model, &floor, &mut contact, &mut |p| {
            max_in_contact = max_in_contact.max(p.contact.nodes_in_contact)
        })
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
