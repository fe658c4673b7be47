//! Structured box meshes: `n³` cubic cells over `[0, size]³`, as hexahedra or each cell
//! split into 6 tetrahedra around its main diagonal (the Kuhn split, conforming across
//! cells). Both kinds share one node grid, numbered x fastest, so a hexahedral and a
//! tetrahedral solution can be compared node by node. [`jittered_box_mesh`] moves the
//! interior nodes at random (seeded, [`SplitMix64`]) for irregular meshes. The one box
//! generator of the workspace: benchmarks, tests and the stability map use it; real anatomy
//! comes from files.

use nalgebra::Point3;

use crate::rng::SplitMix64;
use crate::{Element, Mesh};

/// Index of grid node (i, j, k) of an `n³`-cell box.
pub fn grid_index(n: usize, i: usize, j: usize, k: usize) -> usize {
    (k * (n + 1) + j) * (n + 1) + i
}

/// The box mesh, hexahedra (`tets == false`) or Kuhn tetrahedra, every element positively
/// oriented, with no sets.
pub fn box_mesh(n: usize, size: f64, tets: bool) -> Mesh {
    cuboid_mesh([n; 3], [size; 3], tets)
}

/// [`box_mesh`] with `cells[c]` cells over `[0, size[c]]` along axis `c` (a column, a slab),
/// nodes numbered x fastest, then y, then z.
pub fn cuboid_mesh(cells: [usize; 3], size: [f64; 3], tets: bool) -> Mesh {
    let [nx, ny, nz] = cells;
    let index = |i: usize, j: usize, k: usize| (k * (ny + 1) + j) * (nx + 1) + i;
    let h: [f64; 3] = std::array::from_fn(|c| size[c] / cells[c] as f64);
    let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                nodes.push(Point3::new(i as f64 * h[0], j as f64 * h[1], k as f64 * h[2]));
            }
        }
    }
    let mut elements = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let v = [
                    index(i, j, k),
                    index(i + 1, j, k),
                    index(i + 1, j + 1, k),
                    index(i, j + 1, k),
                    index(i, j, k + 1),
                    index(i + 1, j, k + 1),
                    index(i + 1, j + 1, k + 1),
                    index(i, j + 1, k + 1),
                ];
                if tets {
                    // Six positively oriented tetrahedra around the diagonal 0–6.
                    for t in [
                        [0, 1, 2, 6],
                        [0, 2, 3, 6],
                        [0, 3, 7, 6],
                        [0, 7, 4, 6],
                        [0, 4, 5, 6],
                        [0, 5, 1, 6],
                    ] {
                        elements.push(Element::tet4(t.map(|q| v[q])));
                    }
                } else {
                    elements.push(Element::hex8(v));
                }
            }
        }
    }
    Mesh::new(nodes, elements)
}

/// [`box_mesh`] with every interior grid node moved by up to `jitter × h` per axis (`h` the
/// cell size), uniformly at random from `seed`: x, y, z of each interior node in node order.
/// A tetrahedron the jitter turned inside out has its vertices 1 and 2 swapped, so every
/// element keeps a positive orientation (for `jitter < 0.25` none is turned).
pub fn jittered_box_mesh(n: usize, size: f64, tets: bool, jitter: f64, seed: u64) -> Mesh {
    let mut mesh = box_mesh(n, size, tets);
    let amount = jitter * size / n as f64;
    let mut rng = SplitMix64::new(seed);
    for k in 1..n {
        for j in 1..n {
            for i in 1..n {
                let p = &mut mesh.nodes[grid_index(n, i, j, k)];
                for c in 0..3 {
                    p[c] += amount * (2.0 * rng.uniform() - 1.0);
                }
            }
        }
    }
    for e in 0..mesh.elements.len() {
        if tets && mesh.element_volume(e) < 0.0 {
            mesh.elements[e].nodes_mut().swap(1, 2);
        }
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both kinds fill the box exactly (volume size³), every element positive, and the
    /// mesh passes validation.
    #[test]
    fn boxes_fill_their_volume_with_positive_elements() {
        for tets in [true, false] {
            let m = box_mesh(3, 2.0, tets);
            assert!(m.validate().first_error().is_none());
            let vols: Vec<f64> = (0..m.elements.len()).map(|e| m.element_volume(e)).collect();
            assert!(vols.iter().all(|&v| v > 0.0));
            assert!((vols.iter().sum::<f64>() - 8.0).abs() < 1e-12);
            assert_eq!(m.elements.len(), if tets { 6 * 27 } else { 27 });
            assert_eq!(m.nodes.len(), 64);
        }
    }

    /// Jitter moves interior nodes only, by at most `jitter × h`, reproducibly; the box
    /// still fills its volume with positive elements.
    #[test]
    fn jitter_moves_interior_nodes_only() {
        for tets in [true, false] {
            let (plain, m) = (box_mesh(4, 2.0, tets), jittered_box_mesh(4, 2.0, tets, 0.2, 5));
            assert_eq!(m, jittered_box_mesh(4, 2.0, tets, 0.2, 5));
            let mut moved = 0;
            for (a, b) in plain.nodes.iter().zip(&m.nodes) {
                let on_boundary = (0..3).any(|c| a[c] == 0.0 || a[c] == 2.0);
                let d = (b - a).amax();
                assert!(if on_boundary { d == 0.0 } else { d <= 0.2 * 0.5 });
                moved += (d > 0.0) as usize;
            }
            assert_eq!(moved, 27);
            let vols: Vec<f64> = (0..m.elements.len()).map(|e| m.element_volume(e)).collect();
            assert!(vols.iter().all(|&v| v > 0.0));
            assert!((vols.iter().sum::<f64>() - 8.0).abs() < 1e-12);
        }
    }
}
