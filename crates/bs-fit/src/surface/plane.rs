//! The scan's surface near one point of the patch: a robust plane through the scan's
//! points in a cylinder along the patch's normal there (moving least squares of degree one).
//!
//! The patch may be millimetres from its data (the brain has not moved yet), so the points
//! are gathered along the normal line: those whose distance from the line is below
//! the radius `R` and whose distance along it is below `max_distance`. Each weighs
//! `(1 − (d/R)²)²` by its distance `d` from the line, times Tukey's biweight of its distance
//! from the plane ([`crate::robust`], at the scale re-estimated from the points' own
//! distances, never below `σ`); the plane is the weighted least-squares plane (the normal
//! the weighted covariance's smallest eigenvector), refined a few times from a first plane
//! normal to the line at the points' median height (a plain first fit would be tilted by
//! outliers stacked off the surface). A plane needs
//! enough weight (`MIN_WEIGHT` points' worth) and points around the line, not beside it:
//! the weighted centroid's offset from the line tapers the node's coverage to zero between
//! `R/4` and `3R/4`, so a node at the edge of the scanned area fades out instead of being
//! pulled by a plane extrapolated from one side.

use bs_mesh::{Point3, Vector3};

use crate::robust;

/// Fewer points' worth of weight than this: no plane; up to one and a half times as much
/// the coverage tapers in (a point of the patch does not drop out at once when a scan point
/// leaves its cylinder).
pub const MIN_WEIGHT: f64 = 4.0;

/// Refinements of the robust weights.
const ROUNDS: usize = 4;

/// The normal comes from points within up to this many radii of the line: `1 + min(1,
/// 4σ/R)` of them (a noisy scan's plane tilts by about `σ / (R √N)`; an exact one needs no
/// wider neighbourhood, which would only bend its normal by the surface's curvature).
pub const TILT: f64 = 2.0;

/// The wide radius of a cylinder.
pub fn wide_radius(c: &Cylinder) -> f64 {
    c.radius * (1.0 + (4.0 * c.sigma / c.radius).min(TILT - 1.0))
}

/// The coverage is 1 while the near points' centroid lies within `EDGE.0` radii of the
/// line, 0 beyond `EDGE.1`.
const EDGE: (f64, f64) = (0.2, 0.45);

/// A node's plane of the scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalPlane {
    /// Unit normal, on the node normal's side.
    pub normal: Vector3<f64>,
    /// A point of the plane (the weighted centroid).
    pub point: Point3<f64>,
    /// How much the node is covered, in [0, 1] (the centroid-offset taper).
    pub coverage: f64,
    /// The robust scale of the points' distances from the plane.
    pub scale: f64,
}

/// The cylinder's shape and the noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    pub radius: f64,
    pub length: f64,
    pub sigma: f64,
}

/// The robust plane of `points` (the candidates near the point, any order) around the line
/// through `x` along the unit `n`, `nearest` the distance from `x` to the scan's nearest
/// point; `None` when too few points are near.
pub fn fit(
    x: &Point3<f64>,
    n: &Vector3<f64>,
    points: &[Point3<f64>],
    c: &Cylinder,
    nearest: f64,
    scratch: &mut Vec<Sample>,
) -> Option<LocalPlane> {
    let wide = wide_radius(c);
    scratch.clear();
    for p in points {
        let d = p - x;
        let along = d.dot(n);
        let across = (d - n * along).norm();
        if along.abs() <= c.length && across < wide {
            let kernel =
                |r: f64| if across < r { (1.0 - (across / r).powi(2)).powi(2) } else { 0.0 };
            scratch.push(Sample { p: *p, near: kernel(c.radius), wide: kernel(wide) });
        }
    }
    // The first plane: normal to the line at the near points' weighted median height along
    // it (outliers stacked off the surface pull a mean, and tilt a plain fit); then
    // Tukey-weighted planes at the scale of the residuals, over the wide neighbourhood.
    let mut heights: Vec<(f64, f64)> =
        scratch.iter().filter(|s| s.near > 0.0).map(|s| (n.dot(&(s.p - x)), s.near)).collect();
    let median = weighted_median(&mut heights)?;
    let mut normal = *n;
    let mut centre = x + n * median;
    let mut residuals = Vec::with_capacity(scratch.len());
    let mut scale = c.sigma;
    for _ in 0..ROUNDS {
        residuals.clear();
        residuals
            .extend(scratch.iter().filter(|s| s.near > 0.0).map(|s| normal.dot(&(s.p - centre))));
        scale = robust::scale(residuals.iter().copied(), c.sigma, &mut Vec::new());
        let (plane_n, plane_c) = (normal, centre);
        let weight = |s: &Sample| s.wide * robust::tukey(plane_n.dot(&(s.p - plane_c)), scale);
        centre = centroid(scratch, weight)?;
        normal = smallest_direction(scratch, &centre, weight).unwrap_or(normal);
        if normal.dot(n) < 0.0 {
            normal = -normal;
        }
    }
    // The height from the near points only, the normal from the wide ones: a plane's tilt
    // is its noisy part, and a tilted spring pushes the patch sideways.
    let weight = |s: &Sample| s.near * robust::tukey(normal.dot(&(s.p - centre)), scale);
    let total: f64 = scratch.iter().map(weight).sum();
    if total < MIN_WEIGHT {
        return None;
    }
    let centre = centroid(scratch, weight)?;
    let offset = {
        let d = centre - x;
        (d - n * d.dot(n)).norm()
    };
    let along = normal.dot(&(x - centre)).abs();
    let coverage = smoothstep((EDGE.1 * c.radius - offset) / ((EDGE.1 - EDGE.0) * c.radius))
        * smoothstep(2.0 * (total / MIN_WEIGHT - 1.0))
        * smoothstep((nearest + 2.0 * c.radius - along) / c.radius);
    (coverage > 0.0).then_some(LocalPlane { normal, point: centre, coverage, scale })
}

/// A scan point with its kernel weights at the near and the wide radius.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    p: Point3<f64>,
    near: f64,
    wide: f64,
}

/// The weighted centroid (weights `f(sample)`), `None` without weight.
fn centroid(samples: &[Sample], f: impl Fn(&Sample) -> f64) -> Option<Point3<f64>> {
    let (mut sum, mut total) = (Vector3::zeros(), 0.0);
    for s in samples {
        let w = f(s);
        sum += s.p.coords * w;
        total += w;
    }
    (total > 0.0).then(|| Point3::from(sum / total))
}

/// The direction of least weighted spread about `centre`.
fn smallest_direction(
    samples: &[Sample],
    centre: &Point3<f64>,
    f: impl Fn(&Sample) -> f64,
) -> Option<Vector3<f64>> {
    let mut m = nalgebra::Matrix3::zeros();
    for s in samples {
        let d = s.p - centre;
        m += d * d.transpose() * f(s);
    }
    let e = nalgebra::SymmetricEigen::new(m);
    let k = e.eigenvalues.imin();
    let v: Vector3<f64> = e.eigenvectors.column(k).into();
    (v.norm() > 0.0).then(|| v.normalize())
}

/// The weighted median of `(value, weight)` pairs; `None` without weight.
fn weighted_median(v: &mut [(f64, f64)]) -> Option<f64> {
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = v.iter().map(|(_, w)| w).sum();
    let mut acc = 0.0;
    for (x, w) in v.iter() {
        acc += w;
        if acc >= 0.5 * total && total > 0.0 {
            return Some(*x);
        }
    }
    None
}

/// `t²(3 − 2t)` of `t` clamped to [0, 1].
fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nearest(pts: &[Point3<f64>]) -> f64 {
        pts.iter().map(|p| p.coords.norm()).fold(f64::INFINITY, f64::min)
    }

    fn cyl() -> Cylinder {
        Cylinder { radius: 3.0, length: 10.0, sigma: 0.2 }
    }

    /// Noisy points on a tilted plane 5 mm from the node: the plane comes back within the
    /// noise's share; a fifth of gross outliers change nothing.
    #[test]
    fn a_noisy_plane_with_outliers_is_recovered() {
        let mut rng = bs_mesh::rng::SplitMix64::new(5);
        let normal = Vector3::new(0.1, -0.2, 1.0).normalize();
        let origin = Point3::new(0.0, 0.0, 5.0);
        let (u, v) =
            (normal.cross(&Vector3::x()).normalize(), normal.cross(&Vector3::y()).normalize());
        let mut pts: Vec<Point3<f64>> = (0..400)
            .map(|_| {
                origin
                    + u * rng.range(-4.0, 4.0)
                    + v * rng.range(-4.0, 4.0)
                    + normal * (0.2 * rng.normal())
            })
            .collect();
        for p in pts.iter_mut().step_by(5) {
            *p += normal * 3.0;
        }
        let plane =
            fit(&Point3::origin(), &Vector3::z(), &pts, &cyl(), nearest(&pts), &mut Vec::new())
                .unwrap();
        assert!(plane.normal.dot(&normal) > 0.995, "{}", plane.normal);
        // The plane passes through the origin's column at 5 (along its normal).
        assert!(plane.normal.dot(&(plane.point - origin)).abs() < 0.08, "{:?}", plane);
        // The scale is the residuals' MAD: a fifth of outliers inflate it by a third.
        assert!(plane.coverage > 0.99 && (0.18..0.35).contains(&plane.scale), "{plane:?}");
    }

    /// Points beside the line, not around it: the coverage falls to zero; too few: none.
    #[test]
    fn a_node_beside_its_data_is_not_covered() {
        let pts: Vec<Point3<f64>> = (0..100)
            .map(|k| Point3::new(2.5 + 0.004 * k as f64, 0.01 * k as f64 - 0.5, 1.0))
            .collect();
        assert!(
            fit(&Point3::origin(), &Vector3::z(), &pts, &cyl(), nearest(&pts), &mut Vec::new())
                .is_none()
        );
        let few = vec![Point3::new(0.1, 0.0, 1.0), Point3::new(0.0, 0.1, 1.0)];
        assert!(
            fit(&Point3::origin(), &Vector3::z(), &few, &cyl(), nearest(&few), &mut Vec::new())
                .is_none()
        );
    }
}
