//! The basis of boundary fields on a node set: three translations, then [`BUMPS`] Gaussian
//! bumps along the outward normal.

use bs_mesh::{Mesh, Point3, Vector3};
use nalgebra::DVector;

/// Gaussian normal bumps of the basis (besides the three translations).
pub const BUMPS: usize = 4;

/// The basis of boundary fields on `nodes` of `mesh`: three translations, then [`BUMPS`]
/// Gaussian bumps along the outward normal, centred at nodes spread by farthest-point
/// sampling, their width 0.75 × the mean distance between the centres' nearest neighbours.
pub fn basis(mesh: &Mesh, nodes: &[usize]) -> Vec<Vec<Vector3<f64>>> {
    let mut modes: Vec<Vec<Vector3<f64>>> =
        (0..3).map(|k| vec![Vector3::ith(k, 1.0); nodes.len()]).collect();
    let normals = normals(mesh, nodes);
    let x: Vec<Point3<f64>> = nodes.iter().map(|&n| mesh.nodes[n]).collect();
    let centres = farthest_points(&x, BUMPS.min(x.len()));
    let spacing = centres
        .iter()
        .map(|&i| {
            centres
                .iter()
                .filter(|&&j| j != i)
                .map(|&j| (x[i] - x[j]).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .filter(|d| d.is_finite())
        .sum::<f64>()
        / centres.len().saturating_sub(1).max(1) as f64;
    let width = (0.75 * spacing).max(f64::MIN_POSITIVE);
    for &c in &centres {
        modes.push(
            x.iter()
                .zip(&normals)
                .map(|(xi, n)| n * (-(xi - x[c]).norm_squared() / (2.0 * width * width)).exp())
                .collect(),
        );
    }
    modes
}

/// The boundary field of amplitudes `a`: `Σ_k a_k modes_k`.
pub fn field(modes: &[Vec<Vector3<f64>>], a: &DVector<f64>) -> Vec<Vector3<f64>> {
    let mut b = vec![Vector3::zeros(); modes.first().map_or(0, Vec::len)];
    for (m, &ak) in modes.iter().zip(a.iter()) {
        for (bi, v) in b.iter_mut().zip(m) {
            *bi += v * ak;
        }
    }
    b
}

/// Outward unit normals at `nodes` from the boundary faces among them.
fn normals(mesh: &Mesh, nodes: &[usize]) -> Vec<Vector3<f64>> {
    let mut index = vec![usize::MAX; mesh.nodes.len()];
    for (k, &n) in nodes.iter().enumerate() {
        index[n] = k;
    }
    let mut out = vec![Vector3::zeros(); nodes.len()];
    let b = mesh.boundary();
    for t in &b.surface.triangles {
        let f = t.map(|k| b.volume_node[k]);
        if f.iter().all(|&n| index[n] != usize::MAX) {
            let [a, bb, c] = f.map(|n| mesh.nodes[n]);
            let m = (bb - a).cross(&(c - a));
            for n in f {
                out[index[n]] += m;
            }
        }
    }
    out.iter().map(|v| v.try_normalize(0.0).unwrap_or_else(Vector3::z)).collect()
}

/// `k` indices of `x` spread by farthest-point sampling from the one nearest the centroid.
fn farthest_points(x: &[Point3<f64>], k: usize) -> Vec<usize> {
    if x.is_empty() || k == 0 {
        return Vec::new();
    }
    let centroid = Point3::from(x.iter().map(|p| p.coords).sum::<Vector3<f64>>() / x.len() as f64);
    let first =
        (0..x.len()).min_by(|&a, &b| (x[a] - centroid).norm().total_cmp(&(x[b] - centroid).norm()));
    let mut chosen = vec![first.unwrap_or(0)];
    let mut dist: Vec<f64> = x.iter().map(|p| (p - x[chosen[0]]).norm()).collect();
    while chosen.len() < k {
        let next = (0..x.len()).max_by(|&a, &b| dist[a].total_cmp(&dist[b])).unwrap_or(0);
        if dist[next] == 0.0 {
            break;
        }
        chosen.push(next);
        for (d, p) in dist.iter_mut().zip(x) {
            *d = d.min((p - x[next]).norm());
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Farthest-point sampling against brute force on a line: the middle first, then the
    /// two ends, then the points halfway.
    #[test]
    fn farthest_points_spread_from_the_centre() {
        let x: Vec<Point3<f64>> = (0..9).map(|i| Point3::new(i as f64, 0.0, 0.0)).collect();
        let c = farthest_points(&x, 3);
        assert_eq!(c[0], 4);
        assert_eq!(
            c[1..].iter().copied().collect::<std::collections::BTreeSet<_>>(),
            [0, 8].into()
        );
        assert!(farthest_points(&x, 0).is_empty());
        // Coincident points stop the sampling: nothing is farther than 0.
        assert_eq!(farthest_points(&[Point3::origin(); 3], 3), vec![0]);
    }

    #[test]
    fn the_field_is_the_weighted_sum_of_the_modes() {
        let modes = vec![vec![Vector3::x(); 2], vec![Vector3::new(0.0, 1.0, 2.0); 2]];
        let b = field(&modes, &DVector::from_vec(vec![2.0, -1.0]));
        assert_eq!(b, vec![Vector3::new(2.0, -1.0, -2.0); 2]);
    }
}
