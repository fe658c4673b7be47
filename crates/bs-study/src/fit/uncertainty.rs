//! `cargo xtask fit uncertainty`: is the fit's σ calibrated? The fit study's truths (the
//! craniotomy's sag, straight and tilted 30°, and gravity 0°/30°/60° off the window's axis
//! with the level and direction estimated), each scanned with several noise draws (the
//! target case: σ 1 mm, half the window, 5 % outliers, 2 mm misalignment with bone
//! points), fitted, and σ sampled ([`bs_scene::uncertainty`]); the true error is the fit's
//! minus the truth's displacement.

use std::fmt::Write as _;
use std::path::Path;

use bs_mesh::Vector3;
use bs_scene::uncertainty::{UncertaintyParams, sample};
use bs_scene::{Prepared, Run};

use super::gravity::{self, Load};
use super::truth::{self, Case, Truth};

/// Samples of each σ.
pub const SAMPLES: usize = 32;

/// Held-out landmarks per fit (`[uncertainty] held_out`, drawn as the landmark study's: 5–25
/// mm under the window) and their noise per axis (mm).
pub const HELD_OUT: usize = 15;
pub const HELD_OUT_SIGMA: f64 = 0.5;

/// How one σ-field matches the true error.
#[derive(Debug, Clone, Copy)]
pub struct Calibration {
    /// Fraction of (node, axis) whose true error lies within 2σ (nodes with σ > 0).
    pub coverage: f64,
    /// Mean |e|² over mean tr Σ (nodes with σ > 0).
    pub ratio: f64,
    /// Spearman rank correlation of total σ with |e| over the deep nodes.
    pub spearman: f64,
    /// Deep nodes: the predicted mean error (mean √tr Σ) and the true one.
    pub predicted: f64,
    pub error: f64,
    /// The σ-scale that would put 95 % of (node, axis) within 2σ.
    pub scale95: f64,
}

/// One fit's calibration: σ from the fit's posterior alone (`raw`) and scaled by its
/// held-out landmarks (`scaled`).
#[derive(Debug, Clone)]
pub struct Row {
    pub truth: String,
    pub seed: u64,
    pub raw: Calibration,
    pub scaled: Calibration,
    /// The held-out landmarks' estimate of the scale and the factor applied.
    pub estimate: f64,
    pub scale: f64,
    pub fit_seconds: f64,
    pub sigma_seconds: f64,
}

/// The calibration of `sigma × k` against the true error `e` (`deep`: the deep nodes).
fn calibration(e: &[Vector3<f64>], sigma: &[[f64; 3]], k: f64, deep: &[usize]) -> Calibration {
    let total = |a: usize| k * sigma[a].iter().map(|s| s * s).sum::<f64>().sqrt();
    let live: Vec<usize> = (0..e.len()).filter(|&a| total(a) > 0.0).collect();
    let (mut within, mut count, mut e2, mut tr) = (0usize, 0usize, 0.0, 0.0);
    let mut z = Vec::new();
    for &a in &live {
        for (ek, &s) in e[a].iter().zip(&sigma[a]) {
            if s > 0.0 {
                count += 1;
                within += usize::from(ek.abs() <= 2.0 * k * s);
                z.push(ek.abs() / (k * s));
            }
        }
        e2 += e[a].norm_squared();
        tr += total(a).powi(2);
    }
    z.sort_by(f64::total_cmp);
    let z95 = z.get(((z.len() as f64 * 0.95) as usize).min(z.len().saturating_sub(1)));
    let deep: Vec<usize> = deep.iter().copied().filter(|&a| total(a) > 0.0).collect();
    let sig: Vec<f64> = deep.iter().map(|&a| total(a)).collect();
    let err: Vec<f64> = deep.iter().map(|&a| e[a].norm()).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    Calibration {
        coverage: within as f64 / count.max(1) as f64,
        ratio: e2 / tr,
        spearman: spearman(&sig, &err),
        predicted: mean(&sig),
        error: mean(&err),
        scale95: z95.map_or(f64::NAN, |z| z / 2.0),
    }
}

/// The calibration of the fit of `scene` against `t`.
fn calibrate(t: &Truth, scene: &Path, label: &str, seed: u64) -> Result<Row, String> {
    let p = Prepared::load(scene).map_err(|e| e.to_string())?;
    let mut run = Run::prepare(p).map_err(|e| e.to_string())?;
    let solved = run.solve(&mut |_| {}).map_err(|e| e.to_string())?;
    let params = UncertaintyParams { samples: SAMPLES, seed, ..Default::default() };
    let u = sample(&mut run, &solved, &params).map_err(|e| e.to_string())?;
    let e: Vec<Vector3<f64>> =
        solved.solution.displacements.iter().zip(&t.u).map(|(a, b)| a - b).collect();
    let (estimate, scale) = u.held_out.as_ref().map_or((1.0, 1.0), |h| (h.estimate, h.scale));
    Ok(Row {
        truth: label.to_string(),
        seed,
        raw: calibration(&e, &u.sigma, 1.0 / scale, &t.deep),
        scaled: calibration(&e, &u.sigma, 1.0, &t.deep),
        estimate,
        scale,
        fit_seconds: solved.solve_seconds,
        sigma_seconds: u.seconds,
    })
}

/// `scene`'s text with the `[uncertainty]` table of `HELD_OUT` landmarks of `t` (drawn
/// with `seed`), written into `dir`.
fn with_held_out(t: &Truth, scene: String, dir: &Path, seed: u64) -> Result<String, String> {
    let pairs = super::landmarks::pairs(t, HELD_OUT, HELD_OUT_SIGMA, seed + 1000);
    super::landmarks::write_pairs(&dir.join("held-out.csv"), &pairs)?;
    Ok(format!("{scene}\n[uncertainty]\nheld_out = \"held-out.csv\"\nsigma = {HELD_OUT_SIGMA:?}\n"))
}

/// Spearman's rank correlation (ties broken by order; the values are continuous).
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    pearson(&ranks(a), &ranks(b))
}

fn ranks(v: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..v.len()).collect();
    order.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
    let mut r = vec![0.0; v.len()];
    for (rank, &i) in order.iter().enumerate() {
        r[i] = rank as f64;
    }
    r
}

/// Pearson's correlation.
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len()) as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt().max(f64::MIN_POSITIVE)
}

/// The study's rows (`quick`: one push and one gravity truth, one draw each).
pub fn rows(quick: bool) -> Result<Vec<Row>, String> {
    let mesh_dir = truth::regions().display().to_string();
    let root = crate::util::root().join("target/fit-uncertainty");
    let seeds: &[u64] = if quick { &[47] } else { &[47, 48, 49, 50] };
    let mut rows = Vec::new();
    let mut run = |t: &Truth,
                   label: &str,
                   scene: &dyn Fn(&Case, &Path) -> Result<String, String>| {
        for &seed in seeds {
            let dir = root.join(format!("{}-{seed}", rows.len()));
            std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
            let case = Case { seed, ..Case::target() };
            let path = dir.join("scene.toml");
            crate::util::write(&path, &with_held_out(t, scene(&case, &dir)?, &dir, seed)?)?;
            let row = calibrate(t, &path, label, seed)?;
            let (r, c) = (&row.raw, &row.scaled);
            eprintln!(
                "{label}, seed {seed}: coverage {:.1} % → {:.1} % (× {:.2}), |e|²/trΣ {:.2} → {:.2}, Spearman {:.2}, predicted {:.3} → {:.3} / true {:.3} mm ({:.1} s + {:.1} s)",
                100.0 * r.coverage,
                100.0 * c.coverage,
                row.scale,
                r.ratio,
                c.ratio,
                r.spearman,
                r.predicted,
                c.predicted,
                r.error,
                row.fit_seconds,
                row.sigma_seconds
            );
            rows.push(row);
        }
        Ok::<(), String>(())
    };
    let tilts: &[f64] = if quick { &[0.0] } else { &[0.0, 30.0] };
    for &tilt in tilts {
        let dir = root.join(format!("push-{tilt}"));
        let t = truth::truth_tilted(&dir, &mesh_dir, tilt)?;
        let label = format!("craniotomy sag, {tilt}° off the window's axis");
        run(&t, &label, &|case, dir| truth::write_scan(&t, case, dir, &mesh_dir))?;
    }
    let angles: &[f64] = if quick { &[30.0] } else { &[0.0, 30.0, 60.0] };
    for &angle in angles {
        let load = Load { angle, depth: 25.0, weight: 0.0 };
        let dir = root.join(format!("gravity-{angle}"));
        let t = gravity::truth(&dir, &mesh_dir, &load)?;
        let label = format!("gravity {}, level and direction estimated", load.label());
        run(&t, &label, &|case, dir| gravity::estimated_scene(&t, &load, case, dir, &mesh_dir))?;
    }
    Ok(rows)
}

/// The table of docs/uncertainty.md, with the case-level correlations.
pub fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "σ from the fit's posterior alone, and scaled by {HELD_OUT} held-out landmarks (noise \
         {HELD_OUT_SIGMA} mm per axis) where they show more error than σ predicts (raw → \
         scaled; the scale's estimate in brackets where it is below 1 and σ is left as it is).\n\n\
         | truth | noise draw | within 2σ (per axis) | mean \\|e\\|² / tr Σ | Spearman σ vs \\|e\\| (deep) | deep mean: predicted / true (mm) | held-out scale | σ scale for 95 % (raw) | fit + σ (s) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let (a, b) = (&r.raw, &r.scaled);
        let scale = if r.estimate < 1.0 {
            format!("1 ({:.2})", r.estimate)
        } else {
            format!("{:.2}", r.scale)
        };
        writeln!(
            s,
            "| {} | {} | {:.1} → {:.1} % | {:.2} → {:.2} | {:.2} | {:.3} → {:.3} / {:.3} | {scale} | {:.1} | {:.1} + {:.1} |",
            r.truth,
            r.seed,
            100.0 * a.coverage,
            100.0 * b.coverage,
            a.ratio,
            b.ratio,
            a.spearman,
            a.predicted,
            b.predicted,
            a.error,
            a.scale95,
            r.fit_seconds,
            r.sigma_seconds
        )
        .unwrap();
    }
    let e: Vec<f64> = rows.iter().map(|r| r.raw.error).collect();
    let raw: Vec<f64> = rows.iter().map(|r| r.raw.predicted).collect();
    let scaled: Vec<f64> = rows.iter().map(|r| r.scaled.predicted).collect();
    writeln!(
        s,
        "\nCase-level correlation of the predicted and the true deep mean error over the {} fits: r = {:.2} from the posterior alone, {:.2} scaled by the held-out landmarks.",
        rows.len(),
        pearson(&raw, &e),
        pearson(&scaled, &e)
    )
    .unwrap();
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rank_correlations_are_those_of_textbook_cases() {
        // Monotone but not linear: Spearman 1, Pearson below 1.
        let a = [1.0, 2.0, 3.0, 4.0, 5.0];
        let b = [1.0, 4.0, 9.0, 16.0, 100.0];
        assert!((spearman(&a, &b) - 1.0).abs() < 1e-12);
        assert!(pearson(&a, &b) < 0.95);
        // Reversed: −1.
        let c = [5.0, 4.0, 3.0, 2.0, 1.0];
        assert!((spearman(&a, &c) + 1.0).abs() < 1e-12);
        // Spearman of ranks 1..5 against 2,1,4,3,5: 1 − 6 Σd²/(n(n²−1)) = 1 − 24/120 = 0.8.
        let d = [2.0, 1.0, 4.0, 3.0, 5.0];
        assert!((spearman(&a, &d) - 0.8).abs() < 1e-12);
    }
}
