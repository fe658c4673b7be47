//! Held-out landmarks (`[uncertainty] held_out`): pairs the fit does not see, whose misses
//! measure the error the posterior leaves out (the model's own), and the factor σ is
//! scaled by where they show more error than σ predicts.
//!
//! The misses `e_l` of `n` held-out pairs are modelled as `N(0, s² Σ_l + τ² I)`: the fit's
//! posterior `Σ_l` at the landmark scaled by `s`, plus the pairs' own noise `τ` per axis.
//! The moment estimate `s² = (Σ |e_l|² − 3 n τ²) / Σ tr Σ_l` is unbiased for that model;
//! σ is scaled by `max(1, s)`: held-out pairs can show that σ is too small, while a σ
//! larger than their misses is left as the data's noise made it (a few noisy pairs cannot
//! tell a too-wide posterior from luck).

use bs_mesh::Vector3;
use serde::{Deserialize, Serialize};

use crate::SceneError;
use crate::measure::pairs::Pairs;
use crate::prepare::Prepared;
use crate::scene::UncertaintySection;

/// The held-out pairs of a scene, located in its mesh.
#[derive(Debug, Clone)]
pub struct HeldOut {
    /// The files, as the report names them.
    pub files: String,
    pub pairs: Pairs,
    pub anchors: Vec<bs_fit::Anchor>,
    /// Their noise per axis (mesh units).
    pub sigma: f64,
}

impl HeldOut {
    /// The scene's held-out pairs (none without `[uncertainty] held_out`); errors name the
    /// file and the line or label, as a `[[measurement]]`'s landmarks do.
    pub fn read(p: &Prepared) -> Result<Option<HeldOut>, SceneError> {
        let Some(UncertaintySection { held_out, sigma }) = &p.scene.uncertainty else {
            return Ok(None);
        };
        let key = "[uncertainty] held_out";
        let pairs =
            crate::measure::pairs::read_pairs(held_out, p.scene.space).map_err(|message| {
                SceneError::Read { scene: p.path.clone(), key: key.into(), message }
            })?;
        let anchors = crate::measure::read::locate_landmarks(
            &p.path, &p.scene, &p.mesh, key, held_out, &pairs,
        )?
        .into_iter()
        .map(|(_, a)| a)
        .collect();
        Ok(Some(HeldOut { files: held_out.describe(), pairs, anchors, sigma: *sigma }))
    }

    /// Each pair's miss: the fitted displacement `u` at its material point minus the pair's
    /// measured displacement.
    pub fn misses(&self, u: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        self.anchors
            .iter()
            .zip(self.pairs.pre.iter().zip(&self.pairs.intra))
            .map(|(a, (pre, intra))| {
                let fitted: Vector3<f64> =
                    a.nodes.iter().zip(&a.weights).map(|(&k, &w)| u[k] * w).sum();
                fitted - (intra - pre)
            })
            .collect()
    }
}

/// What the held-out pairs said, in report.json's `uncertainty.held_out`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeldOutScale {
    /// The files and the number of pairs.
    pub files: String,
    pub landmarks: usize,
    /// Their noise per axis (mesh units).
    pub sigma: f64,
    /// The root mean square of their misses, and what the posterior and their noise
    /// predict for it (`√(mean tr Σ_l + 3τ²)`), before scaling (mesh units).
    pub rms_miss: f64,
    pub rms_predicted: f64,
    /// The moment estimate `s` (module documentation), and the factor σ was scaled by,
    /// `max(1, s)`.
    pub estimate: f64,
    pub scale: f64,
}

/// The scale of σ from the misses `e` of pairs with noise `tau` per axis, where the
/// posterior's per-axis variances are `var` (module documentation). A posterior of zero at
/// every pair leaves σ as it is.
pub fn scale(files: &str, e: &[Vector3<f64>], var: &[Vector3<f64>], tau: f64) -> HeldOutScale {
    let n = e.len().max(1) as f64;
    let e2: f64 = e.iter().map(Vector3::norm_squared).sum();
    let tr: f64 = var.iter().map(|v| v.x + v.y + v.z).sum();
    let noise = 3.0 * e.len() as f64 * tau * tau;
    let estimate = if tr > 0.0 { ((e2 - noise) / tr).max(0.0).sqrt() } else { 1.0 };
    HeldOutScale {
        files: files.to_string(),
        landmarks: e.len(),
        sigma: tau,
        rms_miss: (e2 / n).sqrt(),
        rms_predicted: ((tr + noise) / n).sqrt(),
        estimate,
        scale: estimate.max(1.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bs_mesh::rng::SplitMix64;

    fn draws(s: f64, tau: f64, n: usize, seed: u64) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
        let mut rng = SplitMix64::new(seed);
        let mut e = Vec::new();
        let mut var = Vec::new();
        for k in 0..n {
            // Posterior σ varying over the pairs and axes (0.2–0.8).
            let sd = Vector3::new(0.2, 0.5, 0.8) * (1.0 + (k % 3) as f64) / 2.0;
            let g = Vector3::new(rng.normal(), rng.normal(), rng.normal());
            let noise = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * tau;
            e.push(g.component_mul(&sd) * s + noise);
            var.push(sd.component_mul(&sd));
        }
        (e, var)
    }

    #[test]
    fn the_scale_recovers_the_factor_the_misses_were_drawn_with() {
        // 20 000 pairs: the estimate's sampling error is well under 2 %.
        for s in [1.5, 3.0] {
            let (e, var) = draws(s, 0.5, 20_000, 7);
            let h = scale("x.csv", &e, &var, 0.5);
            assert!((h.estimate / s - 1.0).abs() < 0.02, "{s}: {}", h.estimate);
            assert_eq!(h.scale, h.estimate);
            // The prediction before scaling: E|e|² = s² tr Σ + 3τ² (here s = 1 of it).
            let tr = var.iter().map(|v| v.x + v.y + v.z).sum::<f64>() / e.len() as f64;
            assert!((h.rms_predicted - (tr + 0.75).sqrt()).abs() < 1e-12);
        }
    }

    #[test]
    fn misses_smaller_than_sigma_leave_it_unscaled() {
        let (e, var) = draws(0.5, 0.5, 20_000, 8);
        let h = scale("x.csv", &e, &var, 0.5);
        assert!((h.estimate - 0.5).abs() < 0.03, "{}", h.estimate);
        assert_eq!(h.scale, 1.0);
        // Misses all noise: the estimate is 0 (not NaN), σ unscaled.
        let zero = vec![Vector3::zeros(); 4];
        let h = scale("x.csv", &zero, &var[..4], 0.5);
        assert_eq!((h.estimate, h.scale), (0.0, 1.0));
        let h = scale("x.csv", &e[..4], &zero, 0.5);
        assert_eq!((h.estimate, h.scale), (1.0, 1.0));
    }
}
