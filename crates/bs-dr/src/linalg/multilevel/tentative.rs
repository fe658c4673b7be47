//! The aggregates of a level and its tentative prolongator.
//!
//! * **Aggregates**: the points of a level (mesh nodes, or the centroids of the aggregates
//!   of the level above) in each cell of a regular grid of spacing `h`, numbered in the
//!   cells' order (deterministic).
//! * **Tentative prolongator** (Vaněk, Mandel & Brezina, smoothed aggregation, 1996): per
//!   aggregate, the near null space of the level restricted to its points, orthonormalised
//!   (`B_J = Q_J R_J`): the columns of `Q_J` are the aggregate's six coarse unknowns, and
//!   `R_J` is the near null space of the next level at its node. On the mesh the near null
//!   space is the six rigid-body modes (translations and rotations, `B_a = Π_a [I | −[x_a]×]`
//!   with `Π_a` the node's fixed components removed); below, it is the `R` of the level
//!   above, so every level carries the rigid-body modes exactly.
//! * The modes are orthonormalised about the aggregate's centroid `c` (for conditioning:
//!   `B M_c⁻¹`, with `M_c` the change from rotations about the origin to rotations about
//!   `c`) and `R` is carried back to the origin (`R M_c`). A mode that the aggregate cannot
//!   carry (fixed components: an aggregate of fixed nodes carries none) is a zero column of
//!   `Q`, a zero row of `R` and a dropped unknown of the next level.

use bs_mesh::{Point3, Vector3};
use nalgebra::{Matrix3, SMatrix};

use super::blocks::Blocks;

/// Six near-null-space modes at a point of a level with `R` rows per point.
pub(crate) type Modes<const R: usize> = SMatrix<f64, R, 6>;

/// A 6 × 6 block: the modes of a coarse node, or an operator block between two.
pub(crate) type Matrix6 = SMatrix<f64, 6, 6>;

/// The aggregates of a level.
#[derive(Debug, Clone)]
pub(crate) struct Aggregates {
    /// Aggregate of each point.
    pub(super) of: Vec<u32>,
    /// Centroid of each aggregate (the points of the next level).
    pub(super) centroid: Vec<Point3<f64>>,
}

impl Aggregates {
    /// The points `x` by cells of spacing `h`.
    pub(crate) fn new(x: &[Point3<f64>], h: f64) -> Self {
        let (mut lo, mut hi) = (x[0], x[0]);
        for p in x {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let dims: [usize; 3] = std::array::from_fn(|k| ((hi[k] - lo[k]) / h).floor() as usize + 1);
        let cell = |a: usize| -> usize {
            let idx: [usize; 3] =
                std::array::from_fn(|k| (((x[a][k] - lo[k]) / h) as usize).min(dims[k] - 1));
            (idx[2] * dims[1] + idx[1]) * dims[0] + idx[0]
        };
        let mut order: Vec<(usize, u32)> = (0..x.len()).map(|a| (cell(a), a as u32)).collect();
        order.sort_unstable();
        let mut of = vec![0u32; x.len()];
        let mut centroid = Vec::new();
        let mut start = 0;
        while start < order.len() {
            let mut end = start;
            let mut sum = Vector3::zeros();
            while end < order.len() && order[end].0 == order[start].0 {
                let a = order[end].1 as usize;
                of[a] = centroid.len() as u32;
                sum += x[a].coords;
                end += 1;
            }
            centroid.push(Point3::from(sum / (end - start) as f64));
            start = end;
        }
        Aggregates { of, centroid }
    }

    /// Number of aggregates.
    pub(crate) fn len(&self) -> usize {
        self.centroid.len()
    }

    /// The points of every aggregate, in increasing order.
    fn members(&self) -> Vec<Vec<u32>> {
        let mut m = vec![Vec::new(); self.len()];
        for (a, &j) in self.of.iter().enumerate() {
            m[j as usize].push(a as u32);
        }
        m
    }
}

/// `[c]×`, the matrix of `v ↦ c × v`.
fn cross(c: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -c.z, c.y, c.z, 0.0, -c.x, -c.y, c.x, 0.0)
}

/// `M_c` (`inverse` false) or `M_c⁻¹`: rigid-body coefficients about the origin to those
/// about `c`, `(t, ω) ↦ (t − [c]× ω, ω)`.
fn recentre(c: &Point3<f64>, inverse: bool) -> Matrix6 {
    let mut m = Matrix6::identity();
    let s = if inverse { 1.0 } else { -1.0 };
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(cross(&c.coords) * s));
    m
}

/// The rigid-body modes at mesh nodes `x` with the fixed components removed by `fixed`
/// (`Π_a`, identity for free nodes).
pub(crate) fn rigid_modes(x: &[Point3<f64>], fixed: &[Matrix3<f64>]) -> Vec<Modes<3>> {
    x.iter()
        .zip(fixed)
        .map(|(p, pi)| {
            let mut b = Modes::<3>::zeros();
            b.fixed_view_mut::<3, 3>(0, 0).copy_from(pi);
            b.fixed_view_mut::<3, 3>(0, 3).copy_from(&(pi * -cross(&p.coords)));
            b
        })
        .collect()
}

/// The tentative prolongator of `aggregates` for the modes `b` of its points (one block per
/// row, in its aggregate's column), and the modes of the next level (one per aggregate).
pub(crate) fn tentative<const R: usize>(
    aggregates: &Aggregates,
    b: &[Modes<R>],
) -> (Blocks<f64, R, 6>, Vec<Matrix6>) {
    let mut rows = vec![Modes::<R>::zeros(); b.len()];
    let mut next = Vec::with_capacity(aggregates.len());
    for (j, members) in aggregates.members().iter().enumerate() {
        let c = &aggregates.centroid[j];
        let to_local = recentre(c, true);
        let local: Vec<Modes<R>> = members.iter().map(|&a| b[a as usize] * to_local).collect();
        let (q, r) = orthonormalise(&local);
        for (&a, qa) in members.iter().zip(q) {
            rows[a as usize] = qa;
        }
        next.push(r * recentre(c, false));
    }
    let t = Blocks { ptr: (0..=b.len() as u32).collect(), col: aggregates.of.clone(), val: rows };
    (t, next)
}

/// Modified Gram–Schmidt (two passes) of the six columns of the stacked blocks `b`:
/// `b = q r`, columns of `q` orthonormal or zero (a column below 10⁻⁶ of its norm after the
/// passes is dropped: zero in `q`, its row of `r` zero).
fn orthonormalise<const R: usize>(b: &[Modes<R>]) -> (Vec<Modes<R>>, Matrix6) {
    let mut q: Vec<Modes<R>> = b.to_vec();
    let mut r = Matrix6::zeros();
    let dot = |q: &[Modes<R>], i: usize, j: usize| -> f64 {
        q.iter().map(|m| m.column(i).dot(&m.column(j))).sum()
    };
    for k in 0..6 {
        let norm0 = dot(&q, k, k).sqrt();
        for _ in 0..2 {
            for i in 0..k {
                if r[(i, i)] == 0.0 {
                    continue;
                }
                let d = dot(&q, i, k);
                r[(i, k)] += d;
                for m in q.iter_mut() {
                    let ci = m.column(i).into_owned();
                    m.column_mut(k).axpy(-d, &ci, 1.0);
                }
            }
        }
        let nk = dot(&q, k, k).sqrt();
        if nk > 1e-6 * norm0 && nk > 0.0 {
            r[(k, k)] = nk;
            q.iter_mut().for_each(|m| m.column_mut(k).scale_mut(1.0 / nk));
        } else {
            q.iter_mut().for_each(|m| m.column_mut(k).fill(0.0));
        }
    }
    (q, r)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points() -> Vec<Point3<f64>> {
        (0..64)
            .map(|i| {
                let t = i as f64;
                Point3::new(
                    (i % 4) as f64 + 0.1 * (1.3 * t).sin(),
                    ((i / 4) % 4) as f64 + 0.1 * (0.7 * t).cos(),
                    (i / 16) as f64 + 0.1 * (2.1 * t).sin() + 40.0,
                )
            })
            .collect()
    }

    #[test]
    fn every_point_is_in_the_aggregate_of_its_cell() {
        let x = points();
        let agg = Aggregates::new(&x, 2.0);
        assert_eq!(agg.len(), 8);
        for (a, &j) in agg.of.iter().enumerate() {
            assert!((x[a] - agg.centroid[j as usize]).amax() < 1.5);
        }
    }

    /// The prolongator reproduces the rigid-body modes from the next level's modes
    /// (`T B_next = B`), its columns are orthonormal per aggregate, and a fixed node's
    /// aggregate drops the modes it cannot carry.
    #[test]
    fn the_tentative_prolongator_carries_the_rigid_modes_exactly() {
        let x = points();
        let mut fixed = vec![Matrix3::identity(); x.len()];
        // One aggregate's points held in all components but one point in z only.
        let agg = Aggregates::new(&x, 2.0);
        for (a, &j) in agg.of.iter().enumerate() {
            if j == 0 {
                fixed[a] = Matrix3::zeros();
            }
        }
        let b = rigid_modes(&x, &fixed);
        let (t, next) = tentative(&agg, &b);
        for a in 0..x.len() {
            let (cols, vals) = t.row(a);
            assert_eq!(cols, &[agg.of[a]]);
            let back = vals[0] * next[agg.of[a] as usize];
            assert!((back - b[a]).amax() <= 1e-10, "{back} vs {}", b[a]);
        }
        for (j, members) in agg.members().iter().enumerate() {
            let mut g = Matrix6::zeros();
            for &a in members {
                g += t.row(a as usize).1[0].transpose() * t.row(a as usize).1[0];
            }
            let expect = if j == 0 { Matrix6::zeros() } else { Matrix6::identity() };
            assert!((g - expect).amax() <= 1e-12, "aggregate {j}: {g}");
        }
        // The next level: the modes of aggregates again reproduced by its prolongator.
        let agg2 = Aggregates::new(&agg.centroid, 4.0);
        let (t2, next2) = tentative(&agg2, &next);
        for (j, nj) in next.iter().enumerate() {
            let back = t2.row(j).1[0] * next2[agg2.of[j] as usize];
            assert!((back - nj).amax() <= 1e-9 * nj.amax().max(1.0));
        }
    }
}
