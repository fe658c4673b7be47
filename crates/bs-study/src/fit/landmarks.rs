//! Landmark cases of the fit study: `n` material points 5–25 mm under the craniotomy, their
//! truly displaced positions with noise `σ` per axis, fitted (`[[measurement]] landmarks`)
//! and imposed as today (`[[boundary]] landmarks`: the thin-plate spline of the pairs on
//! the craniotomy nodes, `max_extrapolation = 20`).

use std::fmt::Write as _;
use std::path::Path;

use bs_mesh::rng::SplitMix64;
use bs_mesh::{Point3, Vector3};

use super::study::DeepError;
use super::truth::{self, Truth};

/// Landmark depth below the craniotomy (mm: distance to its nearest node) and the
/// smallest distance between two landmarks.
const DEPTH: (f64, f64) = (5.0, 25.0);
const MIN_SPACING: f64 = 5.0;
/// How far from the window's top a landmark may lie laterally (mm).
const LATERAL: f64 = 35.0;

/// `n` landmark pairs of the truth with noise `sigma`: pre-operative and intra-operative.
pub fn pairs(t: &Truth, n: usize, sigma: f64, seed: u64) -> Vec<(Point3<f64>, Point3<f64>)> {
    let mesh = &t.mesh;
    let mut rng = SplitMix64::new(seed);
    let mut out: Vec<(Point3<f64>, Point3<f64>)> = Vec::new();
    for _ in 0..200_000 {
        if out.len() == n {
            break;
        }
        let e = rng.below(mesh.elements.len());
        let nodes = mesh.elements[e].nodes();
        let mut b: Vec<f64> = (0..4).map(|_| -rng.uniform().max(1e-12).ln()).collect();
        let s: f64 = b.iter().sum();
        b.iter_mut().for_each(|v| *v /= s);
        let x = Point3::from(
            nodes.iter().zip(&b).map(|(&a, &w)| mesh.nodes[a].coords * w).sum::<Vector3<f64>>(),
        );
        let lateral = ((x.x - t.centre.x).powi(2) + (x.y - t.centre.y).powi(2)).sqrt();
        let depth =
            t.nodes.iter().map(|&c| (mesh.nodes[c] - x).norm()).fold(f64::INFINITY, f64::min);
        if lateral > LATERAL || !(DEPTH.0..=DEPTH.1).contains(&depth) {
            continue;
        }
        if out.iter().any(|(p, _)| (p - x).norm() < MIN_SPACING) {
            continue;
        }
        let u: Vector3<f64> = nodes.iter().zip(&b).map(|(&a, &w)| t.u[a] * w).sum();
        let noise = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
        out.push((x, x + u + noise));
    }
    out
}

/// Writes `pairs` as a landmarks CSV.
pub fn write_pairs(path: &Path, pairs: &[(Point3<f64>, Point3<f64>)]) -> Result<(), String> {
    let mut s = String::from("x,y,z,x2,y2,z2\n");
    for (a, b) in pairs {
        writeln!(s, "{:?},{:?},{:?},{:?},{:?},{:?}", a.x, a.y, a.z, b.x, b.y, b.z).unwrap();
    }
    crate::util::write(path, &s)
}

/// One landmark case: the fit's deep error and the imposed spline's.
pub struct LandmarkRow {
    pub n: usize,
    pub seed: u64,
    pub sigma: f64,
    pub fit: DeepError,
    pub seconds: Option<f64>,
    pub spline: DeepError,
}

/// Fits and imposes `n` landmarks at `sigma` in `dir`.
pub fn case(t: &Truth, n: usize, sigma: f64, seed: u64, dir: &Path) -> LandmarkRow {
    let p = pairs(t, n, sigma, seed + n as u64);
    let mesh_dir = truth::regions().display().to_string();
    let name = format!("landmarks-{n}-{}", (sigma * 10.0) as u32);
    let run = |body: String, suffix: &str| -> Result<truth::Solve, String> {
        let scene = dir.join(format!("{name}-{suffix}.toml"));
        crate::util::write(&scene, &truth::scene_text(&body, &mesh_dir))?;
        truth::solve(&scene)
    };
    let fit = write_pairs(&dir.join(format!("{name}.csv")), &p).and_then(|()| {
        run(
            format!(
                "[[measurement]]\nlandmarks = \"{name}.csv\"\nnset = \"CRANIOTOMY\"\nsigma = {}\n",
                sigma.max(0.1)
            ),
            "fit",
        )
    });
    let spline = run(
        format!(
            "[[boundary]]\nnset = \"CRANIOTOMY\"\nlandmarks = \"{name}.csv\"\n\
             max_extrapolation = 20.0\n"
        ),
        "spline",
    );
    LandmarkRow {
        n,
        seed,
        sigma,
        seconds: fit.as_ref().ok().map(|s| s.seconds),
        fit: fit.map(|s| truth::deep_error(t, &s.u)),
        spline: spline.map(|s| truth::deep_error(t, &s.u)),
    }
}

/// The landmark table (Markdown).
pub fn table(rows: &[LandmarkRow]) -> String {
    let mut s = String::from(
        "| landmarks | draw | σ (mm) | fit: deep mean / p95 (mm) | solve (s) | imposed spline: \
         deep mean / p95 (mm) | fit against spline |\n|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let ratio = match (&r.fit, &r.spline) {
            (Ok(f), Ok(s)) => format!("{:+.0} %", 100.0 * (f.0 / s.0 - 1.0)),
            _ => String::new(),
        };
        writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {ratio} |",
            r.n,
            r.seed,
            r.sigma,
            super::study::cell(&r.fit),
            r.seconds.map_or(String::new(), |t| format!("{t:.2}")),
            super::study::cell(&r.spline),
        )
        .unwrap();
    }
    s.push('\n');
    let mut counts: Vec<usize> = rows.iter().map(|r| r.n).collect();
    counts.dedup();
    for n in counts {
        let pick = |f: &dyn Fn(&LandmarkRow) -> &DeepError| -> Option<f64> {
            let v: Vec<f64> = rows
                .iter()
                .filter(|r| r.n == n)
                .map(|r| f(r).as_ref().ok().map(|e| e.0))
                .collect::<Option<_>>()?;
            Some(v.iter().sum::<f64>() / v.len() as f64)
        };
        if let (Some(f), Some(sp)) = (pick(&|r| &r.fit), pick(&|r| &r.spline)) {
            writeln!(
                s,
                "{n} landmarks, mean over the draws: fit {f:.2} mm, spline {sp:.2} mm ({:+.0} %).",
                100.0 * (f / sp - 1.0)
            )
            .unwrap();
        }
    }
    s
}
