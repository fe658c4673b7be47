//! `cargo xtask bench update`: intra-operative updates of the MNI152 demo in a live
//! session. The craniotomy is measured at 1, 2, …, 8 mm (along −z), eight successive
//! updates, each solved warm from the previous state (the first from the reference state:
//! there is none before it); every load is also solved cold (from
//! the reference state, same preparation) in the same process, the ratio and the largest
//! difference printed per update. Then the warped T1 grid after each update (inverse map
//! and resampling; the image already in memory, the pre-operative gap on its grid computed
//! once, as a session would, and timed apart). Peak memory of the process at the end.

use std::path::Path;
use std::time::Instant;

use bs_mesh::Vector3;
use bs_register::registration::{InverseMap, RunResult};
use bs_scene::{BoundaryValues, Prepared, Session, Solved, Update};

use super::page::{Page, say};

fn craniotomy(d: f64) -> Vec<Update> {
    let values = BoundaryValues::Uniform(Vector3::new(0.0, 0.0, -d));
    vec![Update::Boundary { set: "CRANIOTOMY".into(), values }]
}

fn row(label: &str, s: &Solved) -> String {
    let r = &s.solution.report;
    format!(
        "{label:>5} {:>6} {:>6} {:>6} {:>8.3}",
        r.steps, r.linear_iterations, r.force_evaluations, s.solve_seconds
    )
}

fn max_diff(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).amax()).fold(0.0, f64::max)
}

/// Peak resident memory of this process (kB), from /proc (Linux).
fn peak_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

/// Runs the benchmark on the MNI152 demo, or on `scene` (another scene with a CRANIOTOMY
/// node set; its output is printed, docs/benchmarks.md is left alone).
pub fn run(scene: Option<&Path>) -> Result<(), String> {
    let root = crate::util::root();
    let mut page = Page::new("update");
    let default = root.join("fixtures/mni152/scene.toml");
    let scene = scene.unwrap_or(&default);
    let t1 = root.join("fixtures/mni152/t1.nii.gz");
    let e = |e: bs_scene::SceneError| e.to_string();
    let t = Instant::now();
    let mut warm = Session::new(Prepared::load(scene).map_err(e)?).map_err(e)?;
    let prepare = t.elapsed().as_secs_f64();
    let mut cold = Session::new(Prepared::load(scene).map_err(e)?).map_err(e)?;
    say!(page, "MNI152 demo, {} nodes; preparation {prepare:.3} s", warm.displacements().len());
    say!(
        page,
        "update: craniotomy at d mm; warm from the previous update, cold from the reference"
    );
    say!(
        page,
        "{:>5} {:>6} {:>6} {:>6} {:>8} | {:>6} {:>6} {:>6} {:>8} | {:>10} {:>12}",
        "d mm",
        "newton",
        "gmres",
        "forces",
        "warm s",
        "newton",
        "gmres",
        "forces",
        "cold s",
        "warm/cold",
        "max diff mm"
    );
    let mut states = Vec::new();
    let mut parts = Vec::new();
    let mut ratios = Vec::new();
    let mut warm_times = Vec::new();
    for k in 1..=8 {
        let d = k as f64;
        let w = warm.apply(&craniotomy(d), &mut |_| {}).map_err(e)?;
        cold.reset();
        let c = cold.apply(&craniotomy(d), &mut |_| {}).map_err(e)?;
        let diff = max_diff(&w.solution.displacements, &c.solution.displacements);
        let (wu, cu) = (&w.solution.displacements, &c.solution.displacements);
        let worst = (0..wu.len())
            .max_by(|&a, &b| (wu[a] - cu[a]).amax().total_cmp(&(wu[b] - cu[b]).amax()));
        let at = worst.filter(|_| diff > 0.0).map_or(String::new(), |a| {
            let contact = if w.verification.in_contact[a] > 0.0 { ", in contact" } else { "" };
            format!(" (node {}{contact})", warm.run().prepared.mesh.node_ids[a])
        });
        ratios.push(w.solve_seconds / c.solve_seconds);
        warm_times.push(w.solve_seconds);
        say!(
            page,
            "{} | {} | {:>10.3} {:>12.2e}{at}",
            row(&format!("{d}"), &w),
            row("", &c).trim_start(),
            w.solve_seconds / c.solve_seconds,
            diff
        );
        let b = &w.solution.report.breakdown;
        let solver = w.solution.report.elapsed.as_secs_f64();
        parts.push([
            b.forces.as_secs_f64(),
            b.preconditioner.as_secs_f64(),
            b.contact.as_secs_f64(),
            solver,
            w.solve_seconds - solver,
        ]);
        states.push(w.solution.displacements);
    }
    let max_warm = warm_times.iter().copied().fold(0.0, f64::max);
    say!(
        page,
        "warm updates: median {:.3} s, max {max_warm:.3} s; warm/cold median {:.3} (every update verified)",
        median(&mut warm_times.clone()),
        median(&mut ratios)
    );
    say!(
        page,
        "warm updates, seconds: forces, preconditioner, contact | solver in all | verification"
    );
    for (k, p) in parts.iter().enumerate() {
        say!(
            page,
            "{:>5} {:>8.3} {:>8.3} {:>8.3} | {:>8.3} | {:>8.3}",
            k + 1,
            p[0],
            p[1],
            p[2],
            p[3],
            p[4]
        );
    }

    // The warped T1 after each update: inverse map (with the extension to the skull) and
    // trilinear resampling on the template's grid, the image read once before.
    let prepared = &warm.run().prepared;
    let (mesh, skull) = (prepared.mesh.clone(), prepared.skull.clone());
    let (space, units) = (prepared.scene.space, prepared.scene.units);
    let img = bs_image::nifti::read_image(&t1).map_err(|e| e.to_string())?;
    let v = &img.volume;
    let mut warp_times = Vec::new();
    // The pre-operative gap on the T1 grid (reference mesh and skull only): once per session.
    let mut gap: Option<Option<Vec<bool>>> = None;
    for (k, u) in states.into_iter().enumerate() {
        let t = Instant::now();
        let result = RunResult::new(Path::new("(update)"), mesh.clone(), u, space, units)
            .map_err(|e| e.to_string())?
            .with_skull(skull.clone());
        let map = InverseMap::new(&result, &v.grid, &t1).map_err(|e| e.to_string())?;
        let map_seconds = t.elapsed().as_secs_f64();
        // Off the clock: it is the session's work, not the update's.
        if gap.is_none() {
            let t = Instant::now();
            gap = Some(map.preop_gap(&v.grid));
            say!(
                page,
                "pre-operative gap on the T1 grid (once per session, not in the times below): \
                 {:.3} s",
                t.elapsed().as_secs_f64()
            );
        }
        let t = Instant::now();
        let warped = map.warp_with_gap(v, &v.data, gap.as_ref().and_then(|g| g.as_deref()));
        let s = map_seconds + t.elapsed().as_secs_f64();
        warp_times.push(s);
        say!(page, "warped T1 after update {} ({} voxels): {s:.3} s", k + 1, warped.len());
    }
    say!(page, "update -> warped T1 grid: median {:.3} s", median(&mut warp_times));
    match peak_kb() {
        Some(kb) => {
            say!(page, "peak memory (two sessions and the image): {:.0} MiB", kb as f64 / 1024.0)
        }
        None => say!(page, "peak memory: not available on this system"),
    }
    if scene == default { page.write("cargo xtask bench update") } else { Ok(()) }
}
