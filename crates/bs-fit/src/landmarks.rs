//! Landmark pairs measured point-to-point: each landmark is a material point (its
//! pre-operative position located in a tetrahedron: four nodes and barycentric weights)
//! against its intra-operative position, weighted by Tukey's biweight of its distance at
//! the robust scale of all distances. With a stiffness it is a data term (three springs
//! along the axes pull the material point); with stiffness zero it only measures, which is
//! how scenes use it: springs inside the brain are point forces no brain feels, and a
//! scene's landmarks are fitted through the boundary the shift comes from instead
//! (bs-scene's `inverse`, docs/fit.md).
//!
//! The distance of a landmark with isotropic noise `σ` per axis is χ-distributed with three
//! degrees of freedom; divided by `√3` it has the scale of one axis, so the robust scale
//! and the biweight's cut-off (`4.685 s`, `s ≥ σ`) apply to `|r|/√3` as to a surface's
//! one-dimensional distances.

use bs_dr::{DataTerm, Spring, Springs};
use bs_mesh::{Point3, Vector3};

use crate::robust;
use crate::surface::{PointFit, PointStatus};

/// A landmark's material point: four nodes and their barycentric weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anchor {
    pub nodes: [usize; 4],
    pub weights: [f64; 4],
}

impl Anchor {
    /// The material point at `positions`.
    pub fn at(&self, positions: &[Point3<f64>]) -> Point3<f64> {
        let mut p = Vector3::zeros();
        for (&a, &b) in self.nodes.iter().zip(&self.weights) {
            p += b * positions[a].coords;
        }
        Point3::from(p)
    }
}

/// The data term of landmark pairs (see the module documentation).
#[derive(Debug, Clone)]
pub struct LandmarkFit {
    anchors: Vec<Anchor>,
    targets: Vec<Point3<f64>>,
    sigma: f64,
    /// The stiffness of each landmark (force per length).
    stiffness: Vec<f64>,
    fits: Vec<PointFit>,
    scale: f64,
    scratch: Vec<f64>,
}

impl LandmarkFit {
    /// Landmarks at `anchors` (material points) measured at `targets` (intra-operative
    /// positions) with noise `sigma`; `stiffness` per landmark.
    pub fn new(
        anchors: Vec<Anchor>,
        targets: Vec<Point3<f64>>,
        sigma: f64,
        stiffness: Vec<f64>,
    ) -> Self {
        assert_eq!(anchors.len(), targets.len(), "one target per anchor");
        assert_eq!(anchors.len(), stiffness.len(), "one stiffness per anchor");
        let fit = PointFit { status: PointStatus::Inlier, residual: 0.0, weight: 1.0 };
        LandmarkFit {
            fits: vec![fit; anchors.len()],
            anchors,
            targets,
            sigma,
            stiffness,
            scale: sigma,
            scratch: Vec::new(),
        }
    }

    /// Per landmark at the last classification: its distance from its target (length
    /// units, never negative) and robust weight.
    pub fn fits(&self) -> &[PointFit] {
        &self.fits
    }

    /// The landmarks' material points.
    pub fn anchors(&self) -> &[Anchor] {
        &self.anchors
    }

    /// The intra-operative positions.
    pub fn targets(&self) -> &[Point3<f64>] {
        &self.targets
    }

    /// The robust scale at the last classification (per axis).
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The stiffness of each landmark.
    pub fn stiffness(&self) -> &[f64] {
        &self.stiffness
    }

    /// Every landmark's distance from its target at `positions`, and its weight by the
    /// biweight of `distance/√3` at the robust scale of those.
    pub fn classify(&mut self, positions: &[Point3<f64>]) {
        let axis = 3f64.sqrt();
        let distances: Vec<f64> = self
            .anchors
            .iter()
            .zip(&self.targets)
            .map(|(a, t)| (t - a.at(positions)).norm())
            .collect();
        self.scale =
            robust::scale(distances.iter().map(|d| d / axis), self.sigma, &mut self.scratch);
        for (f, &d) in self.fits.iter_mut().zip(&distances) {
            let w = robust::tukey(d / axis, self.scale);
            let status = if w > 0.0 { PointStatus::Inlier } else { PointStatus::Outlier };
            *f = PointFit { status, residual: d, weight: w };
        }
    }
}

impl DataTerm for LandmarkFit {
    /// Three springs per landmark along the axes, `k w` each (`w` its biweight).
    fn linearise(&mut self, positions: &[Point3<f64>], springs: &mut Springs) {
        springs.clear();
        self.classify(positions);
        for (i, a) in self.anchors.iter().enumerate() {
            let k = self.stiffness[i] * self.fits[i].weight;
            if k <= 0.0 {
                continue;
            }
            for axis in 0..3 {
                let direction = Vector3::ith(axis, 1.0);
                springs.push(Spring {
                    nodes: a.nodes,
                    weights: a.weights,
                    direction,
                    target: self.targets[i][axis],
                    stiffness: k,
                });
            }
        }
    }

    fn is_active(&self) -> bool {
        self.stiffness.iter().any(|&k| k > 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tet() -> Vec<Point3<f64>> {
        vec![
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ]
    }

    /// A landmark's springs hold its material point: their residuals at the reference are
    /// the components of (material point − target), and the force they sum to is `k` times
    /// the target's offset, split over the nodes by the weights.
    #[test]
    fn three_springs_pull_the_material_point_to_its_target() {
        let x = tet();
        let anchor = Anchor { nodes: [0, 1, 2, 3], weights: [0.25; 4] };
        let target = Point3::new(0.25, 0.25, 0.25) + Vector3::new(0.1, -0.2, 0.3);
        let mut fit = LandmarkFit::new(vec![anchor], vec![target], 1.0, vec![10.0]);
        let mut springs = Springs::new();
        fit.linearise(&x, &mut springs);
        let u = vec![Vector3::zeros(); 4];
        let mut f = vec![Vector3::zeros(); 4];
        springs.add_forces_into(&x, &u, 1.0, &mut f);
        let total: Vector3<f64> = f.iter().sum();
        // The distance 0.374 is inside the cut-off at σ = 1, weight (1 − (0.216/4.685)²)²;
        // the gradient of the energy points away from the target.
        let w = robust::tukey((0.14f64).sqrt() / 3f64.sqrt(), 1.0);
        let expected = -10.0 * w * Vector3::new(0.1, -0.2, 0.3);
        assert!((total - expected).norm() < 1e-12, "{total} {expected}");
        assert!((f[0] - total / 4.0).norm() < 1e-12);
        assert_eq!(fit.fits()[0].status, PointStatus::Inlier);
        assert!((fit.fits()[0].residual - 0.14f64.sqrt()).abs() < 1e-12);
    }

    /// An outlier among consistent landmarks gets weight zero once the others fit.
    #[test]
    fn an_outlier_gets_no_weight() {
        let x = tet();
        let anchors: Vec<Anchor> = (0..4)
            .map(|k| {
                let mut weights = [0.1; 4];
                weights[k] = 0.7;
                Anchor { nodes: [0, 1, 2, 3], weights }
            })
            .collect();
        let mut targets: Vec<Point3<f64>> = anchors.iter().map(|a| a.at(&x)).collect();
        targets[0].x += 0.01;
        targets[1].y -= 0.01;
        targets[3] += Vector3::new(0.0, 0.0, 5.0);
        let mut fit = LandmarkFit::new(anchors, targets, 0.1, vec![1.0; 4]);
        fit.classify(&x);
        assert_eq!(fit.fits()[3].status, PointStatus::Outlier);
        assert_eq!(fit.fits()[3].weight, 0.0);
        assert!(fit.fits()[..3].iter().all(|f| f.status == PointStatus::Inlier));
    }
}
