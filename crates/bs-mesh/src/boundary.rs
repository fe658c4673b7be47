//! Boundary surface of a volume mesh.

use rayon::prelude::*;

use crate::{Mesh, TriSurface};

/// The outward boundary of a volume mesh: element faces used by exactly one element, as
/// triangles (hex quads split along their 0–2 diagonal), right-hand normals pointing out of
/// the mesh when the elements are positively oriented.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BoundarySurface {
    /// The surface; its vertices are the boundary nodes of the volume mesh.
    pub surface: TriSurface,
    /// Volume node index of each surface vertex (ascending).
    pub volume_node: Vec<usize>,
    /// Volume element index of each surface triangle.
    pub element: Vec<usize>,
}

impl BoundarySurface {
    /// Extracts the boundary of `mesh`. Element node indices must be in range (run
    /// [`Mesh::validate`] first on untrusted meshes); out-of-range indices are skipped.
    pub fn extract(mesh: &Mesh) -> BoundarySurface {
        // Every element face keyed by its sorted node indices (triangles padded with
        // usize::MAX), sorted: a key that occurs once is a boundary face. A sort, not a hash
        // map: 4.5× faster on the MNI152 demo's 69 140 tetrahedra (60 → 13 ms).
        let n = mesh.nodes.len();
        let mut faces: Vec<([usize; 4], u32, u8)> = Vec::with_capacity(mesh.elements.len() * 4);
        for (e, el) in mesh.elements.iter().enumerate() {
            let nodes = el.nodes();
            if nodes.iter().any(|&i| i >= n) {
                continue;
            }
            for (k, local) in el.kind().faces().iter().enumerate() {
                faces.push((face_key(el.kind(), nodes, local), e as u32, k as u8));
            }
        }
        faces.par_sort_unstable_by_key(|f| f.0);
        // Deterministic order: by element, then local face.
        let mut boundary: Vec<(usize, usize)> = faces
            .chunk_by(|a, b| a.0 == b.0)
            .filter(|run| run.len() == 1)
            .map(|run| (run[0].1 as usize, run[0].2 as usize))
            .collect();
        boundary.sort_unstable();

        let mut triangles = Vec::with_capacity(boundary.len() * 2);
        let mut element = Vec::with_capacity(boundary.len() * 2);
        for (e, k) in boundary {
            let el = &mesh.elements[e];
            let nodes = el.nodes();
            let local = &el.kind().faces()[k];
            let g = |i: usize| nodes[local[i]];
            match el.kind() {
                crate::ElementKind::Tet4 => {
                    triangles.push([g(0), g(1), g(2)]);
                    element.push(e);
                }
                crate::ElementKind::Hex8 => {
                    triangles.push([g(0), g(1), g(2)]);
                    triangles.push([g(0), g(2), g(3)]);
                    element.extend([e, e]);
                }
            }
        }

        // Compact to the used nodes, ascending volume index.
        let mut used = vec![false; n];
        for t in &triangles {
            for &v in t {
                used[v] = true;
            }
        }
        let volume_node: Vec<usize> = (0..n).filter(|&i| used[i]).collect();
        let mut local = vec![usize::MAX; n];
        for (s, &v) in volume_node.iter().enumerate() {
            local[v] = s;
        }
        let vertices = volume_node.iter().map(|&v| mesh.nodes[v]).collect();
        let triangles = triangles.into_iter().map(|t| t.map(|v| local[v])).collect();
        BoundarySurface { surface: TriSurface::new(vertices, triangles), volume_node, element }
    }
}

fn face_key(kind: crate::ElementKind, nodes: &[usize], local: &[usize; 4]) -> [usize; 4] {
    let mut key = match kind {
        crate::ElementKind::Tet4 => [nodes[local[0]], nodes[local[1]], nodes[local[2]], usize::MAX],
        crate::ElementKind::Hex8 => local.map(|i| nodes[i]),
    };
    key.sort_unstable();
    key
}

impl Mesh {
    /// The outward boundary surface; see [`BoundarySurface::extract`].
    pub fn boundary(&self) -> BoundarySurface {
        BoundarySurface::extract(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Element;
    use proptest::prelude::*;

    /// A structured grid of `n³` cubes over [0, 1]³, each split into 6 tetrahedra around the
    /// main diagonal (Kuhn triangulation; conforming across cells), interior nodes moved by
    /// up to `jitter × h / 2` per axis.
    pub(crate) fn kuhn_cube(n: usize, jitter: f64, seed: u64) -> Mesh {
        crate::structured::jittered_box_mesh(n, 1.0, true, 0.5 * jitter, seed)
    }

    /// Renumbers nodes and reorders elements pseudo-randomly (same geometry).
    fn shuffled(m: Mesh, seed: u64) -> Mesh {
        let n = m.nodes.len();
        let mut perm: Vec<usize> = (0..n).collect();
        let mut rng = crate::rng::SplitMix64::new(seed);
        for i in (1..n).rev() {
            perm.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
        }
        let mut nodes = vec![m.nodes[0]; n];
        for (old, &new) in perm.iter().enumerate() {
            nodes[new] = m.nodes[old];
        }
        let mut elements: Vec<Element> = m
            .elements
            .iter()
            .map(|e| {
                let mut e = *e;
                for v in e.nodes_mut() {
                    *v = perm[*v];
                }
                e
            })
            .collect();
        elements.reverse();
        Mesh::new(nodes, elements)
    }

    #[test]
    fn unit_hex_boundary_is_twelve_outward_triangles() {
        let m = crate::mesh::tests::unit_hex();
        let b = m.boundary();
        assert_eq!((b.surface.vertices.len(), b.surface.triangles.len()), (8, 12));
        let c = b.surface.check().unwrap();
        assert!(c.is_closed_outward(), "{c:?}");
        approx::assert_relative_eq!(c.signed_volume, 1.0, epsilon = 1e-14);
    }

    #[test]
    fn kuhn_cube_boundary_matches_the_grid() {
        let n = 3;
        let b = kuhn_cube(n, 0.3, 7).boundary();
        // Boundary nodes of an (n+1)^3 grid: all minus the (n-1)^3 interior ones; each of
        // the 6 n×n faces holds 2n² triangles.
        assert_eq!(b.surface.vertices.len(), (n + 1).pow(3) - (n - 1).pow(3));
        assert_eq!(b.surface.triangles.len(), 12 * n * n);
        let c = b.surface.check().unwrap();
        assert!(c.is_closed_outward(), "{c:?}");
        assert_eq!(c.euler_characteristic, 2);
        approx::assert_relative_eq!(c.signed_volume, 1.0, epsilon = 1e-13);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        /// Surface extraction of random unstructured tet meshes of a ball (jittered Kuhn
        /// grids of random size with randomly permuted node numbering and element order)
        /// gives a closed, consistently outward surface with Euler characteristic 2 whose
        /// enclosed volume equals the summed element volumes.
        #[test]
        fn boundary_of_random_tet_ball_is_closed_outward_sphere(
            n in 1usize..5, jitter in 0.0f64..0.45, seed in any::<u64>(),
        ) {
            let m = shuffled(kuhn_cube(n, jitter, seed), seed);
            let total: f64 = (0..m.elements.len()).map(|e| m.element_volume(e)).sum();
            prop_assert!((0..m.elements.len()).all(|e| m.element_volume(e) > 0.0));
            let b = m.boundary();
            let c = b.surface.check().unwrap();
            prop_assert!(c.is_closed_outward(), "{:?}", c);
            prop_assert_eq!(c.euler_characteristic, 2);
            prop_assert_eq!(c.components, 1);
            prop_assert!((c.signed_volume - total).abs() <= 1e-12 * total);
            // Boundary vertices map back to the same coordinates.
            for (s, &v) in b.volume_node.iter().enumerate() {
                prop_assert_eq!(b.surface.vertices[s], m.nodes[v]);
            }
        }
    }
}
