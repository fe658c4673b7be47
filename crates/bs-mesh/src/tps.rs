//! Thin-plate spline interpolation of a vector field from scattered points (landmarks):
//! the 3-D biharmonic kernel φ(r) = r plus an affine part,
//!
//! f(p) = Σᵢ wᵢ |p − pᵢ| + a₀ + A p,
//!
//! with the weights and the affine part from the (n + 4) × (n + 4) system
//! [K P; Pᵀ 0] [w; a] = [v; 0], Kᵢⱼ = |pᵢ − pⱼ|, Pᵢ = (1, xᵢ, yᵢ, zᵢ), solved by LU with
//! partial pivoting. f interpolates the values at the landmarks and reproduces every affine
//! field exactly (the side conditions Pᵀ w = 0 leave an affine field to the affine part).

use nalgebra::{DMatrix, Point3, Vector3};

/// Why landmarks cannot be interpolated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TpsError {
    /// Fewer than 4 landmarks, or all on one plane: the affine part is undetermined.
    #[error(
        "{count} landmarks do not determine a 3-D affine map (at least 4, not all on one plane, \
         are needed)"
    )]
    Degenerate {
        /// How many landmarks were given.
        count: usize,
    },
    /// Different numbers of points and values, or non-finite input.
    #[error("{0}")]
    Input(String),
}

/// A fitted thin-plate spline.
#[derive(Debug, Clone)]
pub struct ThinPlateSpline {
    centres: Vec<Point3<f64>>,
    weights: Vec<Vector3<f64>>,
    /// Constant term and the coefficients of the local x, y, z.
    affine: [Vector3<f64>; 4],
    /// The local frame: q = (p − centre) / scale (a better-conditioned system).
    centre: Vector3<f64>,
    scale: f64,
}

impl ThinPlateSpline {
    /// Fits the spline that takes the value `values[i]` at `points[i]`.
    pub fn fit(points: &[Point3<f64>], values: &[Vector3<f64>]) -> Result<Self, TpsError> {
        Self::fit_smoothing(points, values, 0.0)
    }

    /// The smoothing spline: `λ ≥ 0` added to the kernel's diagonal (in the spline's local
    /// frame, where the landmarks' largest distance from their centroid is 1) trades the
    /// interpolation of the values for a smaller bending; `λ = 0` interpolates, `λ → ∞`
    /// tends to the least-squares affine field. For noisy landmarks (Wahba's smoothing
    /// splines).
    pub fn fit_smoothing(
        points: &[Point3<f64>],
        values: &[Vector3<f64>],
        lambda: f64,
    ) -> Result<Self, TpsError> {
        let n = points.len();
        if values.len() != n {
            return Err(TpsError::Input(format!("{n} points but {} values", values.len())));
        }
        if points.iter().any(|p| !p.iter().all(|x| x.is_finite()))
            || values.iter().any(|v| !v.iter().all(|x| x.is_finite()))
        {
            return Err(TpsError::Input("a landmark has a non-finite coordinate".into()));
        }
        // Affine part determined: the points span 3-D (the centred scatter has rank 3).
        let centre = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n.max(1) as f64;
        let scale = points.iter().map(|p| (p.coords - centre).norm()).fold(0.0, f64::max);
        let mut scatter = nalgebra::Matrix3::zeros();
        for p in points {
            let d = (p.coords - centre) / scale.max(f64::MIN_POSITIVE);
            scatter += d * d.transpose();
        }
        let eig = scatter.symmetric_eigenvalues();
        if n < 4 || eig.min() <= 1e-10 * eig.max().max(f64::MIN_POSITIVE) {
            return Err(TpsError::Degenerate { count: n });
        }
        // Coordinates relative to the centroid and scaled: a better-conditioned system, the
        // same interpolant.
        let local = |p: &Point3<f64>| (p.coords - centre) / scale;
        let m = n + 4;
        let mut a = DMatrix::<f64>::zeros(m, m);
        for i in 0..n {
            let pi = local(&points[i]);
            for j in 0..n {
                a[(i, j)] = (pi - local(&points[j])).norm();
            }
            a[(i, i)] += lambda;
            let row = [1.0, pi.x, pi.y, pi.z];
            for c in 0..4 {
                a[(i, n + c)] = row[c];
                a[(n + c, i)] = row[c];
            }
        }
        let mut rhs = DMatrix::<f64>::zeros(m, 3);
        for i in 0..n {
            for c in 0..3 {
                rhs[(i, c)] = values[i][c];
            }
        }
        let sol = a.lu().solve(&rhs).ok_or(TpsError::Degenerate { count: n })?;
        if sol.iter().any(|x| !x.is_finite()) {
            return Err(TpsError::Degenerate { count: n });
        }
        let row = |r: usize| Vector3::new(sol[(r, 0)], sol[(r, 1)], sol[(r, 2)]);
        Ok(ThinPlateSpline {
            centres: points.iter().map(|p| Point3::from(local(p))).collect(),
            weights: (0..n).map(row).collect(),
            affine: [row(n), row(n + 1), row(n + 2), row(n + 3)],
            centre,
            scale,
        })
    }

    /// The interpolated value at `p`.
    pub fn evaluate(&self, p: &Point3<f64>) -> Vector3<f64> {
        let q = (p.coords - self.centre) / self.scale;
        let [c0, ax, ay, az] = self.affine;
        let mut f = c0 + ax * q.x + ay * q.y + az * q.z;
        for (ci, wi) in self.centres.iter().zip(&self.weights) {
            f += wi * (q - ci.coords).norm();
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points() -> Vec<Point3<f64>> {
        let mut rng = crate::rng::SplitMix64::new(11);
        (0..25)
            .map(|_| {
                Point3::new(rng.range(-50.0, 50.0), rng.range(-40.0, 60.0), rng.range(-30.0, 30.0))
            })
            .collect()
    }

    #[test]
    fn an_affine_field_is_reproduced_exactly_everywhere() {
        let a = nalgebra::Matrix3::new(0.02, -0.01, 0.03, 0.0, 0.05, -0.02, 0.01, 0.0, -0.04);
        let b = Vector3::new(1.5, -2.0, 0.7);
        let f = |p: &Point3<f64>| a * p.coords + b;
        let pts = points();
        let tps = ThinPlateSpline::fit(&pts, &pts.iter().map(f).collect::<Vec<_>>()).unwrap();
        for p in [Point3::new(3.0, 4.0, 5.0), Point3::new(-70.0, 80.0, 40.0), pts[3]] {
            // Exact up to the rounding of a 29 × 29 LU (values ~ 5 mm).
            assert!((tps.evaluate(&p) - f(&p)).norm() < 1e-9, "{p}");
        }
    }

    #[test]
    fn landmark_values_are_interpolated() {
        let pts = points();
        let vals: Vec<Vector3<f64>> =
            pts.iter().map(|p| Vector3::new((p.x / 10.0).sin(), p.y * p.z / 1000.0, 1.0)).collect();
        let tps = ThinPlateSpline::fit(&pts, &vals).unwrap();
        for (p, v) in pts.iter().zip(&vals) {
            assert!((tps.evaluate(p) - v).norm() < 1e-9);
        }
    }

    #[test]
    fn coplanar_or_too_few_landmarks_are_refused() {
        let flat: Vec<Point3<f64>> =
            (0..6).map(|i| Point3::new(i as f64, (i * i) as f64, 0.0)).collect();
        let v = vec![Vector3::zeros(); 6];
        assert_eq!(ThinPlateSpline::fit(&flat, &v).unwrap_err(), TpsError::Degenerate { count: 6 });
        assert!(ThinPlateSpline::fit(&flat[..3], &v[..3]).is_err());
    }
}
