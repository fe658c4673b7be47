//! The scan's evidence about the loads: every measured point's signed distance from the
//! exposed surface of a forward solve (no data pull), with its robust weight over the
//! squared noise scale. bs-fit's classification measures each point against the deformed
//! patch; points on its border or beyond `max_distance` carry no evidence (weight 0).

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
}

impl Residuals {
    /// Inliers counted.
    pub fn inliers(&self) -> usize {
        self.w.iter().filter(|&&w| w > 0.0).count()
    }
}

/// The residuals of the scans of `fits` against the reference `x` displaced by `u`.
pub(crate) fn residuals(fits: &mut Fits, x: &[Point3<f64>], u: &[Vector3<f64>]) -> Residuals {
    let positions: Vec<Point3<f64>> = x.iter().zip(u).map(|(x, d)| x + d).collect();
    let (mut r, mut w, mut matched) = (Vec::new(), Vec::new(), Vec::new());
    for term in &mut fits.terms {
        let Term::Surface(fit) = term else { continue };
        fit.classify(&positions);
        let s2 = fit.scale() * fit.scale();
        for f in fit.fits() {
            let m = matches!(f.status, PointStatus::Inlier | PointStatus::Outlier);
            matched.push(m);
            r.push(if m { f.residual } else { 0.0 });
            w.push(if f.status == PointStatus::Inlier { f.weight / s2 } else { 0.0 });
        }
    }
    Residuals { r: DVector::from_vec(r), w: DVector::from_vec(w), matched }
}
