//! Homogeneous deformations on irregular meshes: every element technology must reproduce a
//! homogeneous field exactly (patch test), so the DR answer must match the closed form up to
//! the DR termination error. DR tolerance 1e-9 × load scale leaves three orders of margin to
//! the asserted 1e-6 relative accuracy (the termination estimate bounds the remaining error
//! for a linearly converging iteration).

use bs_dr::{DrParams, DynamicRelaxation, Loads, NoContact};
use bs_material::Material;
use bs_mesh::Vector3;

use crate::common::*;

const E: f64 = 3000.0;
const NU: f64 = 0.45;

/// Neo-Hookean lateral traction `S_xx` under `F = diag(λt, λt, λz)`, written out
/// independently of bs-material: `S = μ J^(−2/3) (I − I₁/3 C⁻¹) + κ J (J−1) C⁻¹`.
fn s_lateral(lt: f64, lz: f64) -> f64 {
    let mu = E / (2.0 * (1.0 + NU));
    let kappa = E / (3.0 * (1.0 - 2.0 * NU));
    let j = lt * lt * lz;
    let i1 = 2.0 * lt * lt + lz * lz;
    mu * j.powf(-2.0 / 3.0) * (1.0 - i1 / (3.0 * lt * lt)) + kappa * j * (j - 1.0) / (lt * lt)
}

/// Lateral stretch of free uniaxial loading, by bisection to machine precision.
fn lateral_stretch(lz: f64) -> f64 {
    let (mut lo, mut hi) = (0.5, 2.0);
    assert!(s_lateral(lo, lz) < 0.0 && s_lateral(hi, lz) > 0.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if s_lateral(mid, lz) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

fn dr() -> DynamicRelaxation {
    DynamicRelaxation::new(DrParams { tolerance: 1e-9, ..Default::default() })
}

#[test]
fn lateral_stretch_solves_zero_traction() {
    let lt = lateral_stretch(0.8);
    assert!(s_lateral(lt, 0.8).abs() < 1e-9, "residual {}", s_lateral(lt, 0.8));
    // Nearly incompressible-ish (ν = 0.45): J close to but above 0.8 · 1 and below 1.
    assert!(lt > 1.0 && lt * lt * 0.8 < 1.0);
}

#[test]
fn uniaxial_compression_with_symmetry_planes() {
    let size = 1.0;
    let lz = 0.8;
    let lt = lateral_stretch(lz);
    for tech in ALL_TECH {
        let (mesh, model) = cube_model(tech, 3, size, 0.2, Material::neo_hookean(E, NU).unwrap());
        let mut loads = Loads::new(mesh.nodes.len());
        for (i, p) in mesh.nodes.iter().enumerate() {
            for c in 0..3 {
                if p[c].abs() < 1e-12 {
                    loads.fix(i, c).unwrap();
                }
            }
            if (p.z - size).abs() < 1e-12 {
                loads.prescribe(i, 2, (lz - 1.0) * size).unwrap();
            }
        }
        let sol =
            dr().solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
        let exact: Vec<Vector3<f64>> = mesh
            .nodes
            .iter()
            .map(|p| Vector3::new((lt - 1.0) * p.x, (lt - 1.0) * p.y, (lz - 1.0) * p.z))
            .collect();
        let scale = (1.0 - lz) * size;
        let diff = max_diff(&sol.displacements, &exact);
        assert!(
            diff <= 1e-6 * scale,
            "{tech:?}: max nodal error {diff:e} (steps {})",
            sol.report.steps
        );
        // The lateral faces really moved (not a trivially fixed answer): x = 1 face moved by
        // (λt − 1), about 0.07 here.
        let corner = node_index(3, 3, 3, 3);
        assert!((sol.displacements[corner].x - (lt - 1.0)).abs() <= 1e-6 * scale);
    }
}

#[test]
fn simple_shear_with_prescribed_boundary() {
    let size = 1.0;
    let gamma = 0.3;
    for tech in ALL_TECH {
        let (mesh, model) = cube_model(tech, 3, size, 0.2, Material::neo_hookean(E, NU).unwrap());
        let mut loads = Loads::new(mesh.nodes.len());
        for (i, p) in mesh.nodes.iter().enumerate() {
            if on_boundary(p, size) {
                loads.prescribe_node(i, Vector3::new(gamma * p.z, 0.0, 0.0)).unwrap();
            }
        }
        let sol =
            dr().solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
        let mut worst = 0.0f64;
        let mut interior = 0;
        for (i, p) in mesh.nodes.iter().enumerate() {
            if !on_boundary(p, size) {
                interior += 1;
                let exact = Vector3::new(gamma * p.z, 0.0, 0.0);
                worst = worst.max((sol.displacements[i] - exact).amax());
            }
        }
        assert_eq!(interior, 8);
        assert!(worst <= 1e-6 * gamma * size, "{tech:?}: interior error {worst:e}");
    }
}

/// The same uniaxial case on the committed gmsh meshes (unstructured T4 cube, 3×3×3 H8 cube),
/// read with bs-mesh's Abaqus reader.
#[test]
fn uniaxial_compression_on_gmsh_fixtures() {
    use bs_dr::{Model, ModelOptions, Solid, TetFormulation};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/basic");
    let lz = 0.8;
    let lt = lateral_stretch(lz);
    let material = Material::neo_hookean(E, NU).unwrap();
    for (file, tet) in [
        ("cube-t4.inp", TetFormulation::T4),
        ("cube-t4.inp", TetFormulation::T4Anp),
        ("cube-h8.inp", TetFormulation::T4),
    ] {
        let mesh = bs_mesh::io::read_mesh(&dir.join(file)).unwrap();
        let model = Model::uniform(
            &mesh,
            Solid { material, density: 1000.0 },
            ModelOptions { tet, ..Default::default() },
        )
        .unwrap();
        let mut loads = Loads::new(mesh.nodes.len());
        for (i, p) in mesh.nodes.iter().enumerate() {
            for c in 0..3 {
                if p[c].abs() < 1e-9 {
                    loads.fix(i, c).unwrap();
                }
            }
            if (p.z - 1.0).abs() < 1e-9 {
                loads.prescribe(i, 2, lz - 1.0).unwrap();
            }
        }
        let sol =
            dr().solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
        let mut worst = 0.0f64;
        for (i, p) in mesh.nodes.iter().enumerate() {
            let exact = Vector3::new((lt - 1.0) * p.x, (lt - 1.0) * p.y, (lz - 1.0) * p.z);
            worst = worst.max((sol.displacements[i] - exact).amax());
        }
        assert!(worst <= 1e-6 * (1.0 - lz), "{file} {tet:?}: max nodal error {worst:e}");
    }
}

/// Homogeneous simple shear is an equilibrium state of every homogeneous hyperelastic solid,
/// so the same patch test holds for St Venant–Kirchhoff and the brain Ogden law (T4). The
/// Ogden model is built from two solids (same law, different densities, assigned
/// alternately): DR masses are fictitious, so the answer must not change.
#[test]
fn simple_shear_other_laws() {
    use bs_dr::{Model, ModelOptions, Solid};
    use bs_material::OgdenParams;
    let size = 1.0;
    let gamma = 0.3;
    let mesh = tet_cube(3, size, 0.2, 5);
    let svk =
        Solid { material: Material::st_venant_kirchhoff(100.0, 0.1).unwrap(), density: 1000.0 };
    let ogden =
        Solid { material: Material::Ogden(OgdenParams::brain(0.45).unwrap()), density: 1000.0 };
    let heavy_ogden = Solid { density: 5000.0, ..ogden };
    let alternate: Vec<usize> = (0..mesh.elements.len()).map(|e| e % 2).collect();
    let mut loads = Loads::new(mesh.nodes.len());
    for (i, p) in mesh.nodes.iter().enumerate() {
        if on_boundary(p, size) {
            loads.prescribe_node(i, Vector3::new(gamma * p.z, 0.0, 0.0)).unwrap();
        }
    }
    let exact: Vec<Vector3<f64>> =
        mesh.nodes.iter().map(|p| Vector3::new(gamma * p.z, 0.0, 0.0)).collect();
    for (name, model) in [
        ("svk", Model::uniform(&mesh, svk, ModelOptions::default()).unwrap()),
        (
            "ogden",
            Model::new(&mesh, &[ogden, heavy_ogden], &alternate, ModelOptions::default()).unwrap(),
        ),
    ] {
        let sol =
            dr().solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
        let diff = max_diff(&sol.displacements, &exact);
        assert!(diff <= 1e-6 * gamma * size, "{name}: interior error {diff:e}");
    }
}
