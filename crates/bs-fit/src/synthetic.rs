//! A sensor model: the point cloud a laser range scanner or stereo camera would deliver of
//! a known surface, degraded as such sensors degrade it (for studies and tests that need a
//! truth to compare a fit with).
//!
//! Points are sampled uniformly over the area of a triangle patch; a part of the patch may
//! be left unscanned (half or a quarter seen, cut through its centroid); every point gets
//! isotropic Gaussian noise of standard deviation `sigma` per axis; a fraction are outliers
//! moved `outlier_distance` in a random direction (specular highlights, blood, instruments);
//! and the whole scan is misaligned by a rigid motion (the navigation's registration error).

use bs_mesh::rng::SplitMix64;
use bs_mesh::{Point3, Vector3};

use crate::rigid::Rigid;

/// Which part of the patch the scanner sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Coverage {
    /// All of it.
    Full,
    /// The half on the positive side of the plane through the centroid normal to `a`.
    Half {
        /// The plane's normal.
        a: Vector3<f64>,
    },
    /// The quarter on the positive sides of the planes through the centroid normal to `a`
    /// and to `b`.
    Quarter {
        /// The first plane's normal.
        a: Vector3<f64>,
        /// The second plane's normal.
        b: Vector3<f64>,
    },
}

impl Coverage {
    /// Whether the point at offset `d` from the patch centroid is seen.
    pub fn sees(&self, d: &Vector3<f64>) -> bool {
        match self {
            Coverage::Full => true,
            Coverage::Half { a } => d.dot(a) >= 0.0,
            Coverage::Quarter { a, b } => d.dot(a) >= 0.0 && d.dot(b) >= 0.0,
        }
    }
}

/// How a scan degrades the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanParams {
    /// Points per unit area (before the coverage cut).
    pub density: f64,
    /// Noise per axis (standard deviation).
    pub sigma: f64,
    /// The part seen.
    pub coverage: Coverage,
    /// Fraction of outliers, and how far they are moved.
    pub outliers: f64,
    pub outlier_distance: f64,
    /// The misalignment applied to every point.
    pub misalignment: Rigid,
    /// The generator's seed.
    pub seed: u64,
}

/// Uniform points on `triangles` over `vertices`, `density` per unit area (the count rounded
/// per triangle by the generator, so the total is right on average).
pub fn sample_surface(
    vertices: &[Point3<f64>],
    triangles: &[[usize; 3]],
    density: f64,
    rng: &mut SplitMix64,
) -> Vec<Point3<f64>> {
    let mut out = Vec::new();
    for t in triangles {
        let [a, b, c] = t.map(|k| vertices[k]);
        let expected = 0.5 * (b - a).cross(&(c - a)).norm() * density;
        let mut n = expected.floor() as usize;
        if rng.uniform() < expected.fract() {
            n += 1;
        }
        for _ in 0..n {
            let (mut r1, mut r2) = (rng.uniform(), rng.uniform());
            if r1 + r2 > 1.0 {
                (r1, r2) = (1.0 - r1, 1.0 - r2);
            }
            out.push(a + (b - a) * r1 + (c - a) * r2);
        }
    }
    out
}

/// The centroid of points.
pub fn centroid(points: &[Point3<f64>]) -> Point3<f64> {
    let n = points.len().max(1) as f64;
    Point3::from(points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n)
}

/// A scan of the surface `triangles` over `vertices` (see the module documentation). The
/// coverage cut goes through `centre`.
pub fn scan(
    vertices: &[Point3<f64>],
    triangles: &[[usize; 3]],
    centre: &Point3<f64>,
    p: &ScanParams,
) -> Vec<Point3<f64>> {
    let mut rng = SplitMix64::new(p.seed);
    let all = sample_surface(vertices, triangles, p.density, &mut rng);
    all.into_iter()
        .filter(|q| p.coverage.sees(&(q - centre)))
        .map(|q| {
            let mut x = q + Vector3::new(rng.normal(), rng.normal(), rng.normal()) * p.sigma;
            if rng.uniform() < p.outliers {
                x += rng.direction() * p.outlier_distance;
            }
            p.misalignment.apply(&x)
        })
        .collect()
}

/// Points of `p` with isotropic Gaussian noise `sigma` per axis and the misalignment
/// applied (bone points of the same scan).
pub fn perturb(
    points: &[Point3<f64>],
    sigma: f64,
    misalignment: &Rigid,
    seed: u64,
) -> Vec<Point3<f64>> {
    let mut rng = SplitMix64::new(seed);
    points
        .iter()
        .map(|q| {
            let x = q + Vector3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
            misalignment.apply(&x)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> (Vec<Point3<f64>>, Vec<[usize; 3]>) {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(10.0, 0.0, 0.0),
            Point3::new(10.0, 10.0, 0.0),
            Point3::new(0.0, 10.0, 0.0),
        ];
        (v, vec![[0, 1, 2], [0, 2, 3]])
    }

    /// 2 points per unit area on a 10 × 10 square: about 200 points, all on the square;
    /// half coverage keeps about half; noise has the asked standard deviation.
    #[test]
    fn density_coverage_and_noise_are_as_asked() {
        let (v, t) = square();
        let centre = Point3::new(5.0, 5.0, 0.0);
        let base = ScanParams {
            density: 2.0,
            sigma: 0.0,
            coverage: Coverage::Full,
            outliers: 0.0,
            outlier_distance: 0.0,
            misalignment: Rigid::default(),
            seed: 1,
        };
        let all = scan(&v, &t, &centre, &base);
        assert!((all.len() as f64 - 200.0).abs() < 30.0, "{}", all.len());
        assert!(all.iter().all(|p| p.z == 0.0 && (0.0..=10.0).contains(&p.x)));
        let half = scan(
            &v,
            &t,
            &centre,
            &ScanParams { coverage: Coverage::Half { a: Vector3::x() }, ..base },
        );
        assert!(half.iter().all(|p| p.x >= 5.0));
        assert!((half.len() as f64 / all.len() as f64 - 0.5).abs() < 0.1);
        let noisy = scan(&v, &t, &centre, &ScanParams { sigma: 0.5, density: 50.0, ..base });
        let sd = (noisy.iter().map(|p| p.z * p.z).sum::<f64>() / noisy.len() as f64).sqrt();
        assert!((sd - 0.5).abs() < 0.03, "{sd}");
        let moved = ScanParams {
            misalignment: Rigid { translation: Vector3::new(0.0, 0.0, 2.0), ..Rigid::default() },
            ..base
        };
        assert!(scan(&v, &t, &centre, &moved).iter().all(|p| p.z == 2.0));
    }
}
