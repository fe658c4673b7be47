//! The rigid misalignment of intra-operative data, estimated from points the same scan took
//! on bone.
//!
//! The navigation system's patient registration leaves the scan 1–2 mm and a degree or two
//! off the pre-operative frame. Bone does not move during surgery, so points the scanner
//! took on the bone around the craniotomy must lie on the skull surface: the rigid motion
//! `x ↦ R (x − c) + c + t` (`c` the bone points' centroid) that brings them there is the
//! misalignment, and it applies to every point of the scan. The brain points are no
//! evidence for it: the brain has moved, and a rigid fit of the brain alone explains most
//! of a sag as misalignment (on a hidden brain, 4.7 of an 8 mm bell-shaped sag).
//!
//! The estimate is point-to-plane ICP with Tukey weights at the re-estimated scale
//! ([`crate::robust`]) and a weak Gaussian prior on the motion (standard deviations
//! [`RigidParams::prior_translation`] and [`RigidParams::prior_rotation`], several times a
//! navigation system's error): a ring of bone on a nearly spherical skull leaves the
//! rotations about the skull's centre (tangential slides) almost unobserved, and the prior
//! keeps them near zero, where they change no point's distance to the skull.

use bs_contact::Patch;
use bs_mesh::{Point3, Vector3};
use nalgebra::{Matrix6, Rotation3, Vector6};

use crate::robust;

/// A rigid motion `x ↦ R x + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    /// The rotation.
    pub rotation: Rotation3<f64>,
    /// The translation (length units).
    pub translation: Vector3<f64>,
}

impl Default for Rigid {
    fn default() -> Self {
        Rigid { rotation: Rotation3::identity(), translation: Vector3::zeros() }
    }
}

impl Rigid {
    /// `R (x − c) + c + t` written as `R x + t'`.
    fn about(rotation: Rotation3<f64>, centre: &Point3<f64>, t: &Vector3<f64>) -> Rigid {
        Rigid { rotation, translation: centre.coords + t - rotation * centre.coords }
    }

    /// The image of `p`.
    pub fn apply(&self, p: &Point3<f64>) -> Point3<f64> {
        self.rotation * p + self.translation
    }

    /// The rotation as a unit axis and an angle in degrees (the x axis for no rotation).
    pub fn axis_angle_degrees(&self) -> (Vector3<f64>, f64) {
        match self.rotation.axis_angle() {
            Some((axis, angle)) => (axis.into_inner(), angle.to_degrees()),
            None => (Vector3::x(), 0.0),
        }
    }
}

/// The settings of [`fit_rigid`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidParams {
    /// The bone points' noise (standard deviation, length units).
    pub sigma: f64,
    /// Prior standard deviation of the translation (length units).
    pub prior_translation: f64,
    /// Prior standard deviation of the rotation (radians).
    pub prior_rotation: f64,
    /// Bone points farther than this from the skull are not matched.
    pub max_distance: f64,
    /// ICP iterations at most.
    pub iterations: usize,
}

/// The estimated misalignment and how well the bone points fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidFit {
    /// The motion to apply to the scan's points.
    pub rigid: Rigid,
    /// Bone points matched to the skull within `max_distance`, and those inside the robust
    /// cut-off at the end.
    pub matched: usize,
    pub inliers: usize,
    /// RMS distance of the inlier bone points to the skull before and after the motion.
    pub rms_before: f64,
    pub rms_after: f64,
    /// ICP iterations taken.
    pub iterations: usize,
    /// The centre the motion's rotation is about (the bone points' mean), and the posterior
    /// covariance of a small motion `ξ = (δω, δt)` after it, `x ↦ x + δω × (x − c) + δt`
    /// (radians and length units): the inverse of the Gauss–Newton matrix at the answer
    /// (the inlier points' information plus the prior's). What the noise of the bone
    /// points leaves undetermined of the correction ([`RigidFit::perturbed`]).
    pub centre: Point3<f64>,
    pub covariance: Matrix6<f64>,
}

impl RigidFit {
    /// The corrected point `x` moved further by the small motion `xi` (see `covariance`).
    pub fn perturbed(&self, xi: &Vector6<f64>, x: &Point3<f64>) -> Point3<f64> {
        let (omega, t) = (Vector3::new(xi[0], xi[1], xi[2]), Vector3::new(xi[3], xi[4], xi[5]));
        x + omega.cross(&(x - self.centre)) + t
    }
}

/// Why a rigid fit cannot be made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RigidError {
    /// Fewer than six bone points within `max_distance` of the skull.
    TooFewMatched {
        /// Points matched.
        matched: usize,
        /// Points given.
        given: usize,
    },
}

/// One point-to-plane correspondence: the point's offset from the centre, the normal at
/// its closest skull point and the residual along it.
struct Pair {
    arm: Vector3<f64>,
    normal: Vector3<f64>,
    residual: f64,
}

/// Matches `points` moved by `(ω, t)` about `centre` on `skull`.
fn pairs(
    points: &[Point3<f64>],
    skull: &Patch,
    centre: &Point3<f64>,
    motion: &Rigid,
    max: f64,
) -> Vec<Pair> {
    points
        .iter()
        .filter_map(|p| {
            let x = motion.apply(p);
            let at = skull.closest(&x, max)?;
            let [a, b, c] =
                skull.triangles()[at.face as usize].map(|k| skull.vertices()[k as usize]);
            let n = (b - a).cross(&(c - a));
            let normal = if at.distance > 1e-12 * (1.0 + x.coords.norm()) {
                (x - at.point) / at.distance
            } else if n.norm() > 0.0 {
                n.normalize()
            } else {
                return None;
            };
            Some(Pair { arm: x - centre, normal, residual: normal.dot(&(x - at.point)) })
        })
        .collect()
}

/// The robust RMS of the residuals inside the cut-off at scale `s`.
fn rms_inside(pairs: &[Pair], s: f64) -> (f64, usize) {
    let inside: Vec<f64> =
        pairs.iter().map(|p| p.residual).filter(|r| robust::is_inlier(*r, s)).collect();
    if inside.is_empty() {
        return (f64::NAN, 0);
    }
    ((inside.iter().map(|r| r * r).sum::<f64>() / inside.len() as f64).sqrt(), inside.len())
}

/// The misalignment that brings `points` (bone, in the scan's frame) onto `skull` (see the
/// module documentation).
pub fn fit_rigid(
    points: &[Point3<f64>],
    skull: &Patch,
    params: &RigidParams,
) -> Result<RigidFit, RigidError> {
    let given = points.len();
    let centre = if given > 0 {
        Point3::from(points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / given as f64)
    } else {
        Point3::origin()
    };
    let (mut omega, mut t) = (Vector3::zeros(), Vector3::zeros());
    let mut motion = Rigid::default();
    let first = pairs(points, skull, &centre, &motion, params.max_distance);
    if first.len() < 6 {
        return Err(RigidError::TooFewMatched { matched: first.len(), given });
    }
    let mut scratch = Vec::new();
    let s0 = robust::scale(first.iter().map(|p| p.residual), params.sigma, &mut scratch);
    let (rms_before, _) = rms_inside(&first, s0);
    let prior = Vector6::new(
        params.prior_rotation.powi(-2),
        params.prior_rotation.powi(-2),
        params.prior_rotation.powi(-2),
        params.prior_translation.powi(-2),
        params.prior_translation.powi(-2),
        params.prior_translation.powi(-2),
    );
    let mut iterations = 0;
    let mut current = first;
    for _ in 0..params.iterations {
        iterations += 1;
        let s = robust::scale(current.iter().map(|p| p.residual), params.sigma, &mut scratch);
        let (a, mut b) = normal_equations(&current, &prior, s, params.sigma);
        // The prior pulls the whole motion, not the increment, towards zero.
        b -= prior.component_mul(&Vector6::new(omega.x, omega.y, omega.z, t.x, t.y, t.z));
        let Some(step) = a.cholesky().map(|c| c.solve(&b)) else { break };
        let d_omega = Vector3::new(step[0], step[1], step[2]);
        let d_t = Vector3::new(step[3], step[4], step[5]);
        // Compose the small rotation about the centre with the motion so far.
        omega = (Rotation3::new(d_omega) * Rotation3::new(omega)).scaled_axis();
        t += d_t;
        motion = Rigid::about(Rotation3::new(omega), &centre, &t);
        current = pairs(points, skull, &centre, &motion, params.max_distance);
        if current.len() < 6 {
            return Err(RigidError::TooFewMatched { matched: current.len(), given });
        }
        if d_omega.norm() * (1.0 + max_arm(&current)) + d_t.norm() < 1e-6 * params.sigma {
            break;
        }
    }
    let s = robust::scale(current.iter().map(|p| p.residual), params.sigma, &mut scratch);
    let (rms_after, inliers) = rms_inside(&current, s);
    let (a, _) = normal_equations(&current, &prior, s, params.sigma);
    let covariance =
        a.try_inverse().unwrap_or_else(|| Matrix6::from_diagonal(&prior.map(|p| 1.0 / p)));
    Ok(RigidFit {
        centre,
        covariance,
        rigid: motion,
        matched: current.len(),
        inliers,
        rms_before,
        rms_after,
        iterations,
    })
}

/// The Gauss–Newton matrix (the prior's diagonal `prior` plus the robustly weighted
/// points' information at scale `s`) and the right-hand side of the points' residuals.
fn normal_equations(
    pairs: &[Pair],
    prior: &Vector6<f64>,
    s: f64,
    sigma: f64,
) -> (Matrix6<f64>, Vector6<f64>) {
    let (mut a, mut b) = (Matrix6::from_diagonal(prior), Vector6::zeros());
    let inv_s2 = 1.0 / (sigma * sigma);
    for p in pairs {
        let w = robust::tukey(p.residual, s) * inv_s2;
        if w == 0.0 {
            continue;
        }
        let j = p.arm.cross(&p.normal);
        let row = Vector6::new(j.x, j.y, j.z, p.normal.x, p.normal.y, p.normal.z);
        a += row * row.transpose() * w;
        b -= row * (w * p.residual);
    }
    (a, b)
}

fn max_arm(pairs: &[Pair]) -> f64 {
    pairs.iter().map(|p| p.arm.norm()).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bumpy closed test surface (no symmetry leaves a motion unobserved), as a patch.
    fn skull() -> Patch {
        let s = bs_contact::shapes::bumpy_sphere(800, 6, 0.08, 5);
        let tris = s.triangles.iter().map(|t| t.map(|k| k as u32)).collect();
        Patch::new(s.vertices.iter().map(|p| p * 70.0).collect(), tris)
    }

    fn params() -> RigidParams {
        RigidParams {
            sigma: 0.3,
            prior_translation: 5.0,
            prior_rotation: 5f64.to_radians(),
            max_distance: 10.0,
            iterations: 50,
        }
    }

    /// Bone points over a cap of the surface, moved by a known misalignment (2 mm, 2°) with
    /// noise: the fit brings them back to within the noise, and undoes the motion where
    /// the points are.
    #[test]
    fn a_known_misalignment_is_recovered() {
        let patch = skull();
        let mut rng = bs_mesh::rng::SplitMix64::new(9);
        let truth: Vec<Point3<f64>> = patch
            .vertices()
            .iter()
            .filter(|v| v.z > 35.0)
            .map(|v| v + rng.direction() * 0.05)
            .collect();
        assert!(truth.len() > 100, "{}", truth.len());
        let off = Rigid {
            rotation: Rotation3::new(Vector3::new(0.3, -1.0, 0.4).normalize() * 2f64.to_radians()),
            translation: Vector3::new(1.2, -1.5, 0.8),
        };
        let scanned: Vec<Point3<f64>> = truth
            .iter()
            .map(|p| off.apply(p) + Vector3::new(0.0, 0.0, 0.3 * rng.normal()))
            .collect();
        let fit = fit_rigid(&scanned, &patch, &params()).unwrap();
        assert!(fit.rms_before > 1.0, "{}", fit.rms_before);
        assert!(fit.rms_after < 0.4, "{}", fit.rms_after);
        // Where the points are, the corrected scan lies within about the noise of the truth
        // along the surface normal; tangential slides are unobserved but bounded.
        let err = truth
            .iter()
            .zip(&scanned)
            .map(|(t, s)| (fit.rigid.apply(s) - t).norm())
            .fold(0.0, f64::max);
        assert!(err < 1.5, "{err}");
    }

    /// The reported covariance against the spread of the fit over fresh noise (brute
    /// force): a point's correction varies as its linearised posterior says.
    #[test]
    fn the_covariance_is_the_spread_of_the_fit_over_the_noise() {
        let patch = skull();
        let mut rng = bs_mesh::rng::SplitMix64::new(3);
        let truth: Vec<Point3<f64>> =
            patch.vertices().iter().filter(|v| v.z > 40.0).copied().collect();
        let p = params();
        let probe = Point3::new(20.0, -10.0, 60.0);
        let (runs, mut fits, mut at) = (300, Vec::new(), Vec::new());
        for _ in 0..runs {
            let noisy: Vec<Point3<f64>> = truth
                .iter()
                .map(|q| q + Vector3::new(rng.normal(), rng.normal(), rng.normal()) * p.sigma)
                .collect();
            let fit = fit_rigid(&noisy, &patch, &p).unwrap();
            at.push(fit.rigid.apply(&probe));
            fits.push(fit);
        }
        let mean = at.iter().map(|x| x.coords).sum::<Vector3<f64>>() / runs as f64;
        // Isotropic noise: its component along each normal has the variance σ² the
        // covariance assumes. The variance of the probe's correction along each axis, both ways: over the runs,
        // and from the first fit's covariance (ξ ↦ δω × (x − c) + δt is linear in ξ).
        let f = &fits[0];
        let arm = f.rigid.apply(&probe) - f.centre;
        let g = nalgebra::Matrix3x6::from_fn(|i, k| {
            if k < 3 {
                let mut e = Vector3::zeros();
                e[k] = 1.0;
                e.cross(&arm)[i]
            } else {
                if i == k - 3 { 1.0 } else { 0.0 }
            }
        });
        let predicted = g * f.covariance * g.transpose();
        for i in 0..3 {
            let spread =
                at.iter().map(|x| (x.coords[i] - mean[i]).powi(2)).sum::<f64>() / (runs - 1) as f64;
            // 300 runs: the sample variance within about 3 × √(2/300) = 25 % of its value.
            let ratio = spread / predicted[(i, i)];
            assert!(
                (0.75..1.33).contains(&ratio),
                "axis {i}: {spread:e} vs {:e}",
                predicted[(i, i)]
            );
        }
    }

    #[test]
    fn too_few_bone_points_are_an_error() {
        let patch = skull();
        let pts = vec![Point3::new(0.0, 0.0, 70.0); 3];
        assert_eq!(
            fit_rigid(&pts, &patch, &params()),
            Err(RigidError::TooFewMatched { matched: 3, given: 3 })
        );
    }
}
