//! Test meshes built in code (structured grids with jittered interior nodes) and helpers.

use bs_dr::{Model, ModelOptions, Solid, TetFormulation};
use bs_material::Material;
use bs_mesh::{Element, Mesh, Point3, Vector3};

/// Small deterministic LCG in [0, 1).
pub struct Rng(u64);
impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407))
    }
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Grid nodes of an `n×n×n` cube of side `size`; interior nodes moved by up to
/// `jitter × h` per axis.
pub fn grid_nodes(n: usize, size: f64, jitter: f64, seed: u64) -> Vec<Point3<f64>> {
    let h = size / n as f64;
    let mut rng = Rng::new(seed);
    let mut nodes = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let mut p = Point3::new(i as f64 * h, j as f64 * h, k as f64 * h);
                let interior = i > 0 && i < n && j > 0 && j < n && k > 0 && k < n;
                if interior {
                    for c in 0..3 {
                        p[c] += jitter * h * (2.0 * rng.next() - 1.0);
                    }
                }
                nodes.push(p);
            }
        }
    }
    nodes
}

pub fn node_index(n: usize, i: usize, j: usize, k: usize) -> usize {
    i + (n + 1) * (j + (n + 1) * k)
}

fn cell_nodes(n: usize, i: usize, j: usize, k: usize) -> [usize; 8] {
    [
        node_index(n, i, j, k),
        node_index(n, i + 1, j, k),
        node_index(n, i + 1, j + 1, k),
        node_index(n, i, j + 1, k),
        node_index(n, i, j, k + 1),
        node_index(n, i + 1, j, k + 1),
        node_index(n, i + 1, j + 1, k + 1),
        node_index(n, i, j + 1, k + 1),
    ]
}

/// Structured H8 cube (Abaqus/VTK node order).
pub fn hex_cube(n: usize, size: f64, jitter: f64, seed: u64) -> Mesh {
    let nodes = grid_nodes(n, size, jitter, seed);
    let mut elements = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                elements.push(Element::hex8(cell_nodes(n, i, j, k)));
            }
        }
    }
    Mesh::new(nodes, elements)
}

/// T4 cube: every grid cell split into 6 tetrahedra around its 0–6 diagonal (a conforming
/// Kuhn triangulation); with jitter the mesh is irregular.
pub fn tet_cube(n: usize, size: f64, jitter: f64, seed: u64) -> Mesh {
    let nodes = grid_nodes(n, size, jitter, seed);
    let mut elements = Vec::new();
    let paths = [[1, 2], [1, 5], [4, 5], [4, 7], [3, 7], [3, 2]];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let c = cell_nodes(n, i, j, k);
                for pth in paths {
                    let mut t = [c[0], c[pth[0]], c[pth[1]], c[6]];
                    let vol = (nodes[t[1]] - nodes[t[0]])
                        .cross(&(nodes[t[2]] - nodes[t[0]]))
                        .dot(&(nodes[t[3]] - nodes[t[0]]));
                    if vol < 0.0 {
                        t.swap(1, 2);
                    }
                    elements.push(Element::tet4(t));
                }
            }
        }
    }
    Mesh::new(nodes, elements)
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
