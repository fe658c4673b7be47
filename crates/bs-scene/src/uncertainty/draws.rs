//! One sample's change of the equations a fitted answer solves: every scan point moved by
//! its noise (isotropic Gaussian, the measurement's σ per axis, as a scanner's), the rigid
//! correction moved by a draw of its posterior (what the bone points' noise leaves of it,
//! [`bs_fit::RigidFit::covariance`]), and gravity's estimated
//! parameters drawn from their posterior. Each becomes a residual change at the answer (the
//! data springs' forces on the noisy scan minus those on the scan, and minus the change of
//! the dead loads); its response through the converged tangent is the sample's deviation.

use bs_dr::{DataTerm, Springs};
use bs_fit::{Fits, Term};
use bs_mesh::rng::SplitMix64;
use bs_mesh::{Point3, Vector3};
use nalgebra::{DMatrix, DVector};

use crate::SceneError;
use crate::estimate::GravityReport;
use crate::measure::FitState;
use crate::prepare::Prepared;

/// What the samples draw, and the state they are drawn at.
pub(crate) struct Draws<'a> {
    p: &'a Prepared,
    /// The scene's data terms as fitted (their points rigidly corrected), and per
    /// measurement the Cholesky factor of its rigid correction's covariance.
    fits: Fits,
    rigid: Vec<Option<(bs_fit::RigidFit, nalgebra::Matrix6<f64>)>>,
    /// The answer's positions and displacements, and the data forces there.
    positions: Vec<Point3<f64>>,
    u: &'a [Vector3<f64>],
    base: Vec<Vector3<f64>>,
    /// Gravity's estimate (none: not estimated).
    gravity: Option<GravityDraw<'a>>,
}

/// Gravity's estimate, the Cholesky factor of its covariance and the dead loads at it.
struct GravityDraw<'a> {
    report: &'a GravityReport,
    factor: DMatrix<f64>,
    body: Vec<Vector3<f64>>,
}

impl<'a> Draws<'a> {
    /// The draws about the answer `u` of `p` fitted with `fits` (`None`: the data were not
    /// used), gravity estimated as `gravity` says.
    pub(crate) fn new(
        p: &'a Prepared,
        model: &bs_dr::Model,
        fit: Option<&FitState>,
        u: &'a [Vector3<f64>],
        gravity: Option<&'a GravityReport>,
    ) -> Result<Self, SceneError> {
        let positions: Vec<Point3<f64>> =
            model.reference().iter().zip(u).map(|(x, d)| x + d).collect();
        let mut fits = fit.map(|f| f.fits.clone()).unwrap_or_default();
        // The patches at the answer (where their neighbourhoods are sized), whatever state
        // the composition's terms were left in.
        fits.classify(&positions);
        let rigid = fit.map_or_else(Vec::new, |f| {
            f.rigid
                .iter()
                .map(|r| r.and_then(|r| r.covariance.cholesky().map(|c| (r, c.l()))))
                .collect()
        });
        let mut draws = Draws { p, fits, rigid, positions, u, base: Vec::new(), gravity: None };
        draws.base = draws.data_forces(&mut refreshed(&draws.fits), model.reference());
        if let Some(g) = gravity.filter(|g| !g.theta.is_empty()) {
            let n = g.theta.len();
            let cov = DMatrix::from_fn(n, n, |i, j| g.covariance[i][j]);
            // A covariance that is not positive definite (a parameter at its bound) is drawn
            // by its diagonal.
            let diagonal = DVector::from_fn(n, |k, _| cov[(k, k)].max(0.0).sqrt());
            let factor =
                cov.clone().cholesky().map_or_else(|| DMatrix::from_diagonal(&diagonal), |c| c.l());
            let body = crate::estimate::body_at(p, model, g, &vec![0.0; n])?;
            draws.gravity = Some(GravityDraw { report: g, factor, body });
        }
        Ok(draws)
    }

    /// What the samples draw, in words (report.json's `uncertainty.parts`).
    pub(crate) fn parts(&self) -> Vec<String> {
        let mut parts = Vec::new();
        let scans = self.fits.terms.iter().any(|t| matches!(t, Term::Surface(_)));
        if scans {
            parts.push("scan noise".to_string());
        }
        if scans && self.rigid.iter().any(Option::is_some) {
            parts.push("rigid correction from the bone points' noise".to_string());
        }
        if self.gravity.is_some() {
            parts.push("gravity's estimated parameters".to_string());
        }
        parts
    }

    /// The data springs' forces of `fits` at the answer.
    fn data_forces(&self, fits: &mut Fits, reference: &[Point3<f64>]) -> Vec<Vector3<f64>> {
        let mut f = vec![Vector3::zeros(); self.u.len()];
        if fits.terms.is_empty() {
            return f;
        }
        let mut springs = Springs::new();
        fits.linearise(&self.positions, &mut springs);
        springs.add_forces_into(reference, self.u, 1.0, &mut f);
        f
    }

    /// One sample's residual change into `out`.
    pub(crate) fn residual_change(
        &self,
        model: &bs_dr::Model,
        rng: &mut SplitMix64,
        out: &mut [Vector3<f64>],
    ) -> Result<(), SceneError> {
        let mut noisy = self.fits.clone();
        for (k, (m, t)) in self.p.measurements.iter().zip(&mut noisy.terms).enumerate() {
            let Term::Surface(s) = t else { continue };
            let sigma = m.sigma;
            let xi = self.rigid.get(k).and_then(Option::as_ref).map(|(fit, l)| {
                let z = nalgebra::Vector6::from_fn(|_, _| rng.normal());
                (fit, l * z)
            });
            let moved: Vec<Point3<f64>> = s
                .points()
                .iter()
                .map(|q| {
                    let x = q + gaussian(rng) * sigma;
                    xi.as_ref().map_or(x, |(fit, xi)| fit.perturbed(xi, &x))
                })
                .collect();
            s.set_points(moved);
        }
        let f = self.data_forces(&mut noisy, model.reference());
        out.iter_mut().zip(f.iter().zip(&self.base)).for_each(|(o, (a, b))| *o = a - b);
        if let Some(GravityDraw { report: g, factor, body }) = &self.gravity {
            let z =
                DVector::from_iterator(factor.ncols(), (0..factor.ncols()).map(|_| rng.normal()));
            let offset = factor * z;
            let drawn = crate::estimate::body_at(self.p, model, g, offset.as_slice())?;
            // The residual is internal minus dead forces.
            for ((o, d), b) in out.iter_mut().zip(&drawn).zip(body) {
                *o -= d - b;
            }
        }
        Ok(())
    }
}

/// `fits` with every scan's points set again, their planes and densities found afresh as a
/// draw's are (so that the base forces and a draw's differ by the noise alone).
fn refreshed(fits: &Fits) -> Fits {
    let mut fits = fits.clone();
    for t in &mut fits.terms {
        if let Term::Surface(s) = t {
            let points = s.points().to_vec();
            s.set_points(points);
        }
    }
    fits
}

/// A standard normal vector.
fn gaussian(rng: &mut SplitMix64) -> Vector3<f64> {
    Vector3::new(rng.normal(), rng.normal(), rng.normal())
}
