//! The data's evidence about the loads: every scan point's signed distance from the exposed
//! surface of a forward solve (no data pull), and each landmark's three components of its
//! material point's miss, with their robust weights over the squared noise scale. bs-fit's
//! classification measures each point against the deformed patch; points on its border or
//! beyond `max_distance` carry no evidence (weight 0). A landmark is always matched (its
//! material point is in the mesh); an outlier by the biweight weighs 0.

use bs_fit::{Fits, PointStatus, Term};
use bs_mesh::{Point3, Vector3};
use nalgebra::DVector;

/// The residuals of every scan point, stacked over the measurements.
#[derive(Debug, Clone)]
pub(crate) struct Residuals {
    /// Signed distances from the patch (0 where not matched).
    pub r: DVector<f64>,
    /// Robust weight over the squared scale (0 where not an inlier).
    pub w: DVector<f64>,
    /// Whether each point was matched on the patch (inlier or outlier).
    pub matched: Vec<bool>,
    /// Whether each residual is a landmark's component (else a scan point's distance).
    pub landmark: Vec<bool>,
}

impl Residuals {
    /// Scan points with evidence (inliers).
    pub fn inliers(&self) -> usize {
        self.w.iter().zip(&self.landmark).filter(|&(&w, &l)| w > 0.0 && !l).count()
    }

    /// Landmarks with evidence (inliers; three residuals each).
    pub fn landmark_inliers(&self) -> usize {
        self.w.iter().zip(&self.landmark).filter(|&(&w, &l)| w > 0.0 && l).count() / 3
    }
}

/// The residuals of the scans and landmarks of `fits` against the reference `x` displaced
/// by `u`.
pub(crate) fn residuals(fits: &mut Fits, x: &[Point3<f64>], u: &[Vector3<f64>]) -> Residuals {
    let positions: Vec<Point3<f64>> = x.iter().zip(u).map(|(x, d)| x + d).collect();
    let (mut r, mut w, mut matched, mut landmark) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for term in &mut fits.terms {
        match term {
            Term::Surface(fit) => {
                fit.classify(&positions);
                let s2 = fit.scale() * fit.scale();
                for f in fit.fits() {
                    let m = matches!(f.status, PointStatus::Inlier | PointStatus::Outlier);
                    matched.push(m);
                    landmark.push(false);
                    r.push(if m { f.residual } else { 0.0 });
                    w.push(if f.status == PointStatus::Inlier { f.weight / s2 } else { 0.0 });
                }
            }
            Term::Landmarks(fit) => {
                fit.classify(&positions);
                let s2 = fit.scale() * fit.scale();
                for ((a, t), f) in fit.anchors().iter().zip(fit.targets()).zip(fit.fits()) {
                    let miss = a.at(&positions) - t;
                    for k in 0..3 {
                        matched.push(true);
                        landmark.push(true);
                        r.push(miss[k]);
                        w.push(f.weight / s2);
                    }
                }
            }
        }
    }
    Residuals { r: DVector::from_vec(r), w: DVector::from_vec(w), matched, landmark }
}
