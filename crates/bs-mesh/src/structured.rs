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

/// [`box_mesh`] of Kuhn tetrahedra with the node sets `TOP` (z = size) and `BASE` (z = 0),
/// and its elements split into two element sets: `ball` (centroid closer than `radius` to
/// the box's centre) and `rest`. A box with a lesion inside, for tests of regions and
/// resection.
pub fn box_with_ball(n: usize, size: f64, radius: f64, ball: &str, rest: &str) -> Mesh {
    let mut mesh = box_mesh(n, size, true);
    let on = |z: f64, m: &Mesh| (0..m.nodes.len()).filter(|&v| m.nodes[v].z == z).collect();
    let (top, base) = (on(size, &mesh), on(0.0, &mesh));
    mesh.node_sets.insert("TOP".into(), top);
    mesh.node_sets.insert("BASE".into(), base);
    let centre = Point3::new(0.5 * size, 0.5 * size, 0.5 * size);
    let (mut inside, mut outside) = (Vec::new(), Vec::new());
    for (e, el) in mesh.elements.iter().enumerate() {
        let nodes = el.nodes();
        let c = nodes.iter().fold(nalgebra::Vector3::zeros(), |s, &v| s + mesh.nodes[v].coords)
            / nodes.len() as f64;
        if (c - centre.coords).norm() < radius { inside.push(e) } else { outside.push(e) }
    }
    mesh.element_sets.insert(ball.into(), inside);
    mesh.element_sets.insert(rest.into(), outside);
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

    /// The ball's elements are those whose centroid lies inside it, the rest the others: a
    /// partition, and the ball's volume near 4/3 π r³ (within the cells cut by its sphere).
    #[test]
    fn box_with_ball_splits_its_elements_by_centroid() {
        let m = box_with_ball(6, 40.0, 9.0, "BALL", "REST");
        let (ball, rest) = (&m.element_sets["BALL"], &m.element_sets["REST"]);
        assert_eq!(ball.len() + rest.len(), m.elements.len());
        let volume: f64 = ball.iter().map(|&e| m.element_volume(e)).sum();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 9f64.powi(3);
        // Cells of 6.67 mm: the discrete ball is within a shell of one cell of the sphere.
        let shell = 4.0 * std::f64::consts::PI * 81.0 * (40.0 / 6.0);
        assert!((volume - exact).abs() < shell, "{volume} vs {exact}");
        assert_eq!(m.node_sets["TOP"].len(), 49);
        assert_eq!(m.node_sets["BASE"].len(), 49);
    }
}
