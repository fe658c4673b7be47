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

/// One fit's calibration.
#[derive(Debug, Clone)]
pub struct Row {
    pub truth: String,
    pub seed: u64,
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
    pub fit_seconds: f64,
    pub sigma_seconds: f64,
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
    let live: Vec<usize> = (0..e.len()).filter(|&a| u.total(a) > 0.0).collect();
    let (mut within, mut count, mut e2, mut tr) = (0usize, 0usize, 0.0, 0.0);
    let mut z = Vec::new();
    for &a in &live {
        for (ek, &s) in e[a].iter().zip(&u.sigma[a]) {
            if s > 0.0 {
                count += 1;
                within += usize::from(ek.abs() <= 2.0 * s);
                z.push(ek.abs() / s);
            }
        }
        e2 += e[a].norm_squared();
        tr += u.total(a).powi(2);
    }
    z.sort_by(f64::total_cmp);
    let z95 = z[((z.len() as f64 * 0.95) as usize).min(z.len() - 1)];
    let deep: Vec<usize> = t.deep.iter().copied().filter(|&a| u.total(a) > 0.0).collect();
    let sig: Vec<f64> = deep.iter().map(|&a| u.total(a)).collect();
    let err: Vec<f64> = deep.iter().map(|&a| e[a].norm()).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    Ok(Row {
        truth: label.to_string(),
        seed,
        coverage: within as f64 / count.max(1) as f64,
        ratio: e2 / tr,
        spearman: spearman(&sig, &err),
        predicted: mean(&sig),
        error: mean(&err),
        scale95: z95 / 2.0,
        fit_seconds: solved.solve_seconds,
        sigma_seconds: u.seconds,
    })
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
            crate::util::write(&path, &scene(&case, &dir)?)?;
            let row = calibrate(t, &path, label, seed)?;
            eprintln!(
                "{label}, seed {seed}: coverage {:.1} %, |e|²/trΣ {:.2}, Spearman {:.2}, predicted {:.3} / true {:.3} mm ({:.1} s + {:.1} s)",
                100.0 * row.coverage,
                row.ratio,
                row.spearman,
                row.predicted,
                row.error,
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

/// The table of docs/uncertainty.md, with the case-level correlation.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| truth | noise draw | within 2σ (per axis) | mean \\|e\\|² / tr Σ | Spearman σ vs \\|e\\| (deep) | deep mean: predicted / true (mm) | σ scale for 95 % | fit + σ (s) |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        writeln!(
            s,
            "| {} | {} | {:.1} % | {:.2} | {:.2} | {:.3} / {:.3} | {:.1} | {:.1} + {:.1} |",
            r.truth,
            r.seed,
            100.0 * r.coverage,
            r.ratio,
            r.spearman,
            r.predicted,
            r.error,
            r.scale95,
            r.fit_seconds,
            r.sigma_seconds
        )
        .unwrap();
    }
    let p: Vec<f64> = rows.iter().map(|r| r.predicted).collect();
    let e: Vec<f64> = rows.iter().map(|r| r.error).collect();
    writeln!(
        s,
        "\nCase-level correlation of the predicted and the true deep mean error over the {} fits: r = {:.2}.",
        rows.len(),
        pearson(&p, &e)
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
