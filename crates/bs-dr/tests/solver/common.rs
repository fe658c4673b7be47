//! Test meshes built in code (structured grids with jittered interior nodes) and helpers.

use bs_dr::{Loads, Model, ModelOptions, Solid, TetFormulation};
use bs_material::Material;
use bs_mesh::{Mesh, Point3, Vector3, structured};

/// The workspace's seeded generator.
pub use bs_mesh::rng::SplitMix64 as Rng;
pub use bs_mesh::structured::grid_index as node_index;

/// Structured H8 cube (Abaqus/VTK node order) of `n³` cells over `[0, size]³`, interior nodes
/// moved by up to `jitter × h` per axis.
pub fn hex_cube(n: usize, size: f64, jitter: f64, seed: u64) -> Mesh {
    structured::jittered_box_mesh(n, size, false, jitter, seed)
}

/// T4 cube: every grid cell split into 6 tetrahedra around its 0–6 diagonal (a conforming
/// Kuhn triangulation); with jitter the mesh is irregular.
pub fn tet_cube(n: usize, size: f64, jitter: f64, seed: u64) -> Mesh {
    structured::jittered_box_mesh(n, size, true, jitter, seed)
}

/// The three technologies on an `n³` cube: T4 and T4ANP on the tet mesh, H8 on the hex mesh
/// (same nodes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Tech {
    T4,
    T4Anp,
    H8,
}

pub const ALL_TECH: [Tech; 3] = [Tech::T4, Tech::T4Anp, Tech::H8];

pub fn cube_model(
    tech: Tech,
    n: usize,
    size: f64,
    jitter: f64,
    material: Material,
) -> (Mesh, Model) {
    let mesh = match tech {
        Tech::H8 => hex_cube(n, size, jitter, 7),
        _ => tet_cube(n, size, jitter, 7),
    };
    let tet = if tech == Tech::T4Anp { TetFormulation::T4Anp } else { TetFormulation::T4 };
    let model = Model::uniform(
        &mesh,
        Solid { material, density: 1000.0 },
        ModelOptions { tet, ..Default::default() },
    )
    .expect("valid model");
    (mesh, model)
}

pub fn on_boundary(p: &Point3<f64>, size: f64) -> bool {
    (0..3).any(|c| p[c].abs() < 1e-12 || (p[c] - size).abs() < 1e-12)
}

pub fn max_diff(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).amax()))
}

/// Uniaxial compression of a unit cube (T4, ν = 0.45) by 0.2 from the top, with x = 0 and
/// y = 0 symmetry planes and nothing on its bottom: the mesh, the model, the loads and the
/// bottom nodes (for a floor under them, or a z = 0 symmetry plane).
pub fn block_on_floor() -> (Mesh, Model, Loads, Vec<usize>) {
    let material = Material::neo_hookean(3000.0, 0.45).unwrap();
    let (mesh, model) = cube_model(Tech::T4, 3, 1.0, 0.2, material);
    let mut loads = Loads::new(mesh.nodes.len());
    let mut bottom = Vec::new();
    for (i, p) in mesh.nodes.iter().enumerate() {
        if p.x.abs() < 1e-12 {
            loads.fix(i, 0).unwrap();
        }
        if p.y.abs() < 1e-12 {
            loads.fix(i, 1).unwrap();
        }
        if (p.z - 1.0).abs() < 1e-12 {
            loads.prescribe(i, 2, -0.2).unwrap();
        }
        if p.z.abs() < 1e-12 {
            bottom.push(i);
        }
    }
    (mesh, model, loads, bottom)
}
