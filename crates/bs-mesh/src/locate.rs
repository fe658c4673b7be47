//! Point location in a tetrahedral mesh, for carrying a nodal field from one mesh to the
//! points of another (comparing solutions on different mesh densities).
//!
//! A point inside the mesh gets the tetrahedron that contains it and its barycentric
//! weights, so a field linear in each element is reproduced exactly. A point outside (a
//! coarser mesh's boundary node lies up to a facet sagitta outside a finer mesh) gets the
//! nearest tetrahedron by the clamped-barycentric distance and the clamped weights, i.e. the
//! field is extended constantly along the normal of the nearest boundary face or edge.

use nalgebra::{Matrix3, Point3, Vector3};

use crate::{ElementKind, Mesh};

/// Where a point lies in a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Location {
    /// Element index.
    pub element: usize,
    /// Barycentric weights of the element's four nodes (non-negative, sum 1).
    pub weights: [f64; 4],
    /// Distance from the point to the weighted point of the element: 0 inside the mesh.
    pub distance: f64,
}

/// Tetrahedra bucketed on a uniform grid whose cell is at least as large as every
/// tetrahedron's bounding box, so a tetrahedron touches at most 2×2×2 cells.
#[derive(Debug, Clone)]
pub struct TetLocator {
    origin: Point3<f64>,
    cell: f64,
    dims: [usize; 3],
    /// CSR: tets of cell `c` are `items[starts[c]..starts[c + 1]]`.
    starts: Vec<usize>,
    items: Vec<u32>,
    /// Per tet: its first node and the inverse of [x1−x0, x2−x0, x3−x0].
    first: Vec<Point3<f64>>,
    inverse: Vec<Matrix3<f64>>,
    corners: Vec<[Point3<f64>; 4]>,
    elements: Vec<[usize; 4]>,
}

/// Why a mesh cannot be searched.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LocateError {
    /// Only linear tetrahedra are supported.
    #[error("element {id} is a hexahedron; point location supports tetrahedral meshes only")]
    NotTetrahedral {
        /// Element id (file label).
        id: u64,
    },
    /// The mesh has no elements.
    #[error("the mesh has no elements")]
    Empty,
    /// A degenerate tetrahedron has no barycentric coordinates.
    #[error("element {id} is degenerate (zero volume); run `brainshift inspect` on the mesh")]
    Degenerate {
        /// Element id (file label).
        id: u64,
    },
    /// A node of the element has a non-finite coordinate.
    #[error("element {id} has a node with a non-finite coordinate")]
    NonFinite {
        /// Element id (file label).
        id: u64,
    },
    /// More tetrahedra than a lattice location can index (u32).
    #[error("{tetrahedra} tetrahedra are more than lattice location supports (2^32 - 1)")]
    TooLarge {
        /// How many there are.
        tetrahedra: usize,
    },
}

impl TetLocator {
    /// Builds the grid over the mesh's tetrahedra.
    pub fn new(mesh: &Mesh) -> Result<Self, LocateError> {
        let mut elements = Vec::with_capacity(mesh.elements.len());
        for (e, el) in mesh.elements.iter().enumerate() {
            if el.kind() != ElementKind::Tet4 {
                return Err(LocateError::NotTetrahedral { id: mesh.element_ids[e] });
            }
            let n = el.nodes();
            elements.push([n[0], n[1], n[2], n[3]]);
        }
        if elements.is_empty() {
            return Err(LocateError::Empty);
        }
        let corners: Vec<[Point3<f64>; 4]> =
            elements.iter().map(|t| t.map(|i| mesh.nodes[i])).collect();
        let mut first = Vec::with_capacity(corners.len());
        let mut inverse = Vec::with_capacity(corners.len());
        let (mut lo, mut hi) =
            (Point3::from([f64::INFINITY; 3]), Point3::from([-f64::INFINITY; 3]));
        let mut cell = 0.0f64;
        for (e, c) in corners.iter().enumerate() {
            let m = Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]]);
            let inv = m.try_inverse().ok_or(LocateError::Degenerate { id: mesh.element_ids[e] })?;
            first.push(c[0]);
            inverse.push(inv);
            let (a, b) = bbox(c);
            lo = lo.inf(&a);
            hi = hi.sup(&b);
            cell = cell.max((b - a).max());
        }
        let cell = cell.max(1e-12 * (hi - lo).norm()).max(f64::MIN_POSITIVE);
        let dims = [0, 1, 2].map(|k| (((hi[k] - lo[k]) / cell).floor() as usize + 1).max(1));
        let ncell = dims[0] * dims[1] * dims[2];
        let mut per_cell: Vec<Vec<u32>> = vec![Vec::new(); ncell];
        let grid = GridIndex { origin: lo, cell, dims };
        for (e, c) in corners.iter().enumerate() {
            let (a, b) = bbox(c);
            let (ia, ib) = (grid.cell_of(&a), grid.cell_of(&b));
            for i in ia[0]..=ib[0] {
                for j in ia[1]..=ib[1] {
                    for k in ia[2]..=ib[2] {
                        per_cell[grid.flat([i, j, k])].push(e as u32);
                    }
                }
            }
        }
        let mut starts = Vec::with_capacity(ncell + 1);
        let mut items = Vec::new();
        starts.push(0);
        for list in per_cell {
            items.extend(list);
            starts.push(items.len());
        }
        Ok(TetLocator { origin: lo, cell, dims, starts, items, first, inverse, corners, elements })
    }

    /// The node indices of element `e` as the locator sees them.
    pub fn element_nodes(&self, e: usize) -> [usize; 4] {
        self.elements[e]
    }

    /// Where `p` lies: the containing tetrahedron, or the nearest one for a point outside.
    pub fn locate(&self, p: &Point3<f64>) -> Location {
        let grid = GridIndex { origin: self.origin, cell: self.cell, dims: self.dims };
        let c = grid.cell_of(p);
        let mut best: Option<Location> = None;
        let max_ring = self.dims.iter().copied().max().unwrap_or(1);
        for ring in 0..=max_ring {
            for cell in grid.ring(c, ring) {
                for &e in &self.items[self.starts[cell]..self.starts[cell + 1]] {
                    let loc = self.try_element(e as usize, p);
                    if loc.distance == 0.0 {
                        return loc;
                    }
                    if best.is_none_or(|b| loc.distance < b.distance) {
                        best = Some(loc);
                    }
                }
            }
            // Every tetrahedron not yet seen lies in cells of ring ≥ ring + 1 only, at
            // least `ring` cells away from p's cell.
            if let Some(b) = best
                && b.distance <= ring as f64 * self.cell
            {
                return b;
            }
        }
        best.unwrap_or_else(|| self.try_element(0, p))
    }

    /// `values` (one per node of the located mesh) at `p`.
    pub fn interpolate(&self, values: &[Vector3<f64>], p: &Point3<f64>) -> Vector3<f64> {
        let loc = self.locate(p);
        let n = self.elements[loc.element];
        (0..4).map(|k| values[n[k]] * loc.weights[k]).sum()
    }

    fn try_element(&self, e: usize, p: &Point3<f64>) -> Location {
        let l = self.inverse[e] * (p - self.first[e]);
        let w = [1.0 - l.x - l.y - l.z, l.x, l.y, l.z];
        // Rounding: a point on a shared face may read −1e-16 in both neighbours.
        if w.iter().all(|&x| x >= -1e-12) {
            let s: f64 = w.iter().map(|x| x.max(0.0)).sum();
            return Location { element: e, weights: w.map(|x| x.max(0.0) / s), distance: 0.0 };
        }
        // Outside: the closest point of the tetrahedron lies on one of its faces.
        let c = &self.corners[e];
        let q = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]
            .iter()
            .map(|f| crate::closest::closest_point_triangle(p, &c[f[0]], &c[f[1]], &c[f[2]]).0)
            .min_by(|a, b| (p - a).norm_squared().total_cmp(&(p - b).norm_squared()))
            .unwrap_or(c[0]);
        let l = self.inverse[e] * (q - self.first[e]);
        let w = [1.0 - l.x - l.y - l.z, l.x, l.y, l.z].map(|x| x.max(0.0));
        let s: f64 = w.iter().sum();
        let distance = (p - q).norm().max(f64::MIN_POSITIVE);
        Location { element: e, weights: w.map(|x| x / s), distance }
    }
}

fn bbox(c: &[Point3<f64>; 4]) -> (Point3<f64>, Point3<f64>) {
    let mut a = c[0];
    let mut b = c[0];
    for x in &c[1..] {
        a = a.inf(x);
        b = b.sup(x);
    }
    (a, b)
}

struct GridIndex {
    origin: Point3<f64>,
    cell: f64,
    dims: [usize; 3],
}

impl GridIndex {
    fn cell_of(&self, p: &Point3<f64>) -> [usize; 3] {
        [0, 1, 2].map(|k| {
            let x = ((p[k] - self.origin[k]) / self.cell).floor();
            if x.is_nan() || x < 0.0 { 0 } else { (x as usize).min(self.dims[k] - 1) }
        })
    }

    fn flat(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Cells at Chebyshev distance exactly `r` from `c`, inside the grid.
    fn ring(&self, c: [usize; 3], r: usize) -> impl Iterator<Item = usize> + '_ {
        let r = r as isize;
        let range = |k: usize| {
            let lo = (c[k] as isize - r).max(0);
            let hi = (c[k] as isize + r).min(self.dims[k] as isize - 1);
            lo..=hi
        };
        let (ri, rj, rk) = (range(0), range(1), range(2));
        rk.flat_map(move |k| {
            let (ri, rj) = (ri.clone(), rj.clone());
            rj.flat_map(move |j| ri.clone().map(move |i| (i, j, k)))
        })
        .filter(move |&(i, j, k)| {
            let d = (i - c[0] as isize)
                .abs()
                .max((j - c[1] as isize).abs())
                .max((k - c[2] as isize).abs());
            d == r
        })
        .map(|(i, j, k)| self.flat([i as usize, j as usize, k as usize]))
    }
}

/// A nodal vector field of `from` evaluated at the nodes of `to` (see [`TetLocator`]).
pub fn transfer(
    from: &TetLocator,
    values: &[Vector3<f64>],
    points: &[Point3<f64>],
) -> Vec<Vector3<f64>> {
    points.iter().map(|p| from.interpolate(values, p)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Element;

    /// The unit cube of n³ cells, 6 tetrahedra each.
    fn cube(n: usize) -> Mesh {
        crate::structured::box_mesh(n, 1.0, true)
    }

    /// A field linear in x is reproduced exactly inside (closed form) and the located
    /// element contains the point (brute-force check of its weights).
    #[test]
    fn linear_field_is_exact_inside() {
        let m = cube(5);
        let loc = TetLocator::new(&m).unwrap();
        let f = |p: &Point3<f64>| Vector3::new(2.0 * p.x - p.y, 0.5 * p.z + 1.0, p.x + p.y + p.z);
        let values: Vec<_> = m.nodes.iter().map(f).collect();
        let mut rng = crate::rng::SplitMix64::new(12345);
        let mut r = || rng.uniform();
        for _ in 0..2000 {
            let p = Point3::new(r(), r(), r());
            let got = loc.interpolate(&values, &p);
            assert!((got - f(&p)).amax() < 1e-12, "{p}: {got} vs {}", f(&p));
            assert_eq!(loc.locate(&p).distance, 0.0);
        }
        // Nodes map to themselves.
        for (i, p) in m.nodes.iter().enumerate() {
            assert!((loc.interpolate(&values, p) - values[i]).amax() < 1e-12);
        }
    }

    /// A point outside gets the nearest boundary point's value: just above the top face
    /// z = 1, the field equals its value at the foot of the perpendicular; far away, the
    /// nearest corner's.
    #[test]
    fn outside_points_take_the_nearest_boundary_value() {
        let m = cube(4);
        let loc = TetLocator::new(&m).unwrap();
        let values: Vec<_> = m.nodes.iter().map(|p| p.coords).collect();
        let p = Point3::new(0.3, 0.7, 1.05);
        let l = loc.locate(&p);
        assert!((l.distance - 0.05).abs() < 1e-12, "{l:?}");
        assert!((loc.interpolate(&values, &p) - Vector3::new(0.3, 0.7, 1.0)).amax() < 1e-12);
        let far = Point3::new(-3.0, -2.0, 5.0);
        let l = loc.locate(&far);
        assert!((l.distance - (far - Point3::new(0.0, 0.0, 1.0)).norm()).abs() < 1e-9, "{l:?}");
    }

    /// The grid search finds the same distance as a scan of every tetrahedron, for points
    /// inside, near and far outside a jittered mesh.
    #[test]
    fn grid_search_agrees_with_brute_force() {
        let mut m = cube(4);
        let mut s = 99u64;
        let mut r = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        for p in &mut m.nodes {
            p.coords += Vector3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 0.08;
        }
        let loc = TetLocator::new(&m).unwrap();
        for _ in 0..1500 {
            let p = Point3::new(r() * 2.0 - 0.5, r() * 2.0 - 0.5, r() * 2.0 - 0.5);
            let got = loc.locate(&p);
            let brute = (0..m.elements.len())
                .map(|e| loc.try_element(e, &p).distance)
                .fold(f64::INFINITY, f64::min);
            let brute = if brute <= f64::MIN_POSITIVE { 0.0 } else { brute };
            let got_d = if got.distance <= f64::MIN_POSITIVE { 0.0 } else { got.distance };
            assert!((got_d - brute).abs() < 1e-12, "{p}: {got:?} vs {brute}");
            assert!((got.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn hexahedra_are_refused_with_their_id() {
        let mut m = cube(1);
        m.elements.push(Element::hex8([0, 1, 3, 2, 4, 5, 7, 6]));
        m.element_ids.push(77);
        assert_eq!(TetLocator::new(&m).unwrap_err(), LocateError::NotTetrahedral { id: 77 });
    }
}
