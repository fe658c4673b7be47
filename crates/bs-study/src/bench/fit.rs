//! `cargo xtask bench fit`: the cost of fitting a scan against imposing the displacement it
//! measures, in one process on the same brain (fixtures/fit: the MNI152 regions brain,
//! 69k tetrahedra). Cold: the fit of the fixture's scan (`scene.toml`) against the truth's
//! craniotomy displacement imposed (`scene-truth.toml`), each solved from the reference
//! state three times, medians and their ratio. Updates: a live session of each, then four
//! successive intra-operative changes (the scan, and the imposed craniotomy, 0.5 mm
//! deeper each time): the imposed one solved warm from the last state, the scan fitted
//! with the session's preparation from the reference state (bs-scene's `session/points.rs`
//! says why); medians and their ratio. Gravity: fixtures/fit-gravity's fit estimating the
//! level and direction with its scan against the forward solve of the same scene's gravity
//! (`scene-forward.toml`). Uncertainty: the fixture's σ sampled after its fit (`run
//! --uncertainty`'s default samples) against the fit. The table goes into docs/benchmarks.md between its `fit` markers.

use std::fmt::Write as _;
use std::time::Instant;

use bs_mesh::{Point3, Vector3};
use bs_scene::uncertainty::UncertaintyParams;
use bs_scene::{BoundaryValues, Prepared, Run, Session, Update};

use crate::util::{replace_block, root};

const REPEATS: usize = 3;
const UPDATES: usize = 4;
const STEP_MM: f64 = 0.5;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

fn session(name: &str) -> Result<Session, String> {
    let path = root().join("fixtures").join(name);
    let p = Prepared::load(&path).map_err(|e| e.to_string())?;
    Session::new(p).map_err(|e| e.to_string())
}

/// A cold solve of `s`'s own loads (from the reference state): seconds and Newton
/// iterations.
fn cold(s: &mut Session) -> Result<(f64, f64), String> {
    s.reset();
    let t = Instant::now();
    let r = s.solve(&mut |_| {}).map_err(|e| e.to_string())?;
    Ok((t.elapsed().as_secs_f64(), r.solution.report.steps as f64))
}

/// The truth's craniotomy displacements (the imposed scene's file), per node of the set.
fn truth_craniotomy(s: &Session) -> Result<Vec<Vector3<f64>>, String> {
    let nodes = s.set_nodes("CRANIOTOMY").map_err(|e| e.to_string())?;
    let p = &s.run().prepared.prescribed;
    Ok(nodes.iter().map(|&n| Vector3::from_fn(|c, _| p[n][c].unwrap_or(0.0))).collect())
}

/// The fixture's fit and its σ sampled after it (the default samples), each timed: medians
/// of the fit's seconds, the sampling's and its GMRES iterations.
fn uncertainty() -> Result<(f64, f64, f64), String> {
    let (mut fit, mut sigma, mut gmres) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..REPEATS {
        let p =
            Prepared::load(&root().join("fixtures/fit/scene.toml")).map_err(|e| e.to_string())?;
        let mut run = Run::prepare(p).map_err(|e| e.to_string())?;
        let t = Instant::now();
        let solved = run.solve(&mut |_| {}).map_err(|e| e.to_string())?;
        fit.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let u = bs_scene::uncertainty::sample(&mut run, &solved, &UncertaintyParams::default())
            .map_err(|e| e.to_string())?;
        sigma.push(t.elapsed().as_secs_f64());
        gmres.push(u.iterations as f64);
    }
    Ok((median(fit), median(sigma), median(gmres)))
}

/// `cargo xtask bench fit`.
pub fn run() -> Result<(), String> {
    let mut imposed = session("fit/scene-truth.toml")?;
    let mut fit = session("fit/scene.toml")?;
    let (mut ci, mut cf, mut cits) = (Vec::new(), Vec::new(), Vec::new());
    // Interleaved, so that the machine's load falls on both alike.
    for _ in 0..REPEATS {
        ci.push(cold(&mut imposed)?.0);
        let (t, its) = cold(&mut fit)?;
        cf.push(t);
        cits.push(its);
    }
    let base = truth_craniotomy(&imposed)?;
    let scan = bs_mesh::io::points::read_points(&root().join("fixtures/fit/scan.csv"))
        .map_err(|e| e.to_string())?;
    let (mut wi, mut wf, mut its) = (Vec::new(), Vec::new(), Vec::new());
    for k in 1..=UPDATES {
        let dz = Vector3::new(0.0, 0.0, -STEP_MM * k as f64);
        let per_node = base.iter().map(|u| u + dz).collect();
        let t = Instant::now();
        imposed
            .apply(
                &[Update::Boundary {
                    set: "CRANIOTOMY".into(),
                    values: BoundaryValues::PerNode(per_node),
                }],
                &mut |_| {},
            )
            .map_err(|e| e.to_string())?;
        wi.push(t.elapsed().as_secs_f64());
        let deeper: Vec<Point3<f64>> = scan.iter().map(|p| p + dz).collect();
        let t = Instant::now();
        let s = fit
            .update_points(&[("CRANIOTOMY".into(), deeper)], &mut |p: &bs_scene::Progress| {
                if std::env::var_os("BS_DEBUG_FIT").is_some() {
                    eprintln!(
                        "{} load {:.3} err {:.2e} maxu {:.3}",
                        p.step, p.load_factor, p.err, p.max_displacement
                    )
                }
            })
            .map_err(|e| e.to_string())?;
        wf.push(t.elapsed().as_secs_f64());
        its.push(s.solution.report.steps as f64);
    }
    let (ci, cf, wi, wf) = (median(ci), median(cf), median(wi), median(wf));
    let mut table = String::from(
        "| solve | imposed craniotomy (s) | fitted scan (s) | fit / imposed |\n|---|---|---|---|\n",
    );
    writeln!(
        table,
        "| cold, median of {REPEATS} | {ci:.2} | {cf:.2} ({:.0} Newton iterations) | {:.1}× |",
        median(cits),
        cf / ci
    )
    .unwrap();
    writeln!(
        table,
        "| session update, {STEP_MM} mm deeper each time, median of {UPDATES} | {wi:.2} (warm) | \
         {wf:.2} ({:.0} Newton iterations) | {:.1}× |",
        median(its),
        wf / wi
    )
    .unwrap();
    // Gravity estimated with the scan against the forward solve of the same scene's gravity.
    let mut forward = session("fit-gravity/scene-forward.toml")?;
    let mut estimated = session("fit-gravity/scene.toml")?;
    let (mut gf, mut ge, mut solves) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..REPEATS {
        gf.push(cold(&mut forward)?.0);
        estimated.reset();
        let t = Instant::now();
        let r = estimated.solve(&mut |_| {}).map_err(|e| e.to_string())?;
        ge.push(t.elapsed().as_secs_f64());
        solves.push(r.gravity.map_or(0.0, |g| g.solves as f64));
    }
    let (gf, ge) = (median(gf), median(ge));
    writeln!(
        table,
        "| fixtures/fit-gravity: level and direction estimated with the scan, median of {REPEATS} | {gf:.2} (the forward gravity solve) | {ge:.2} ({:.0} solves) | {:.1}× |",
        median(solves),
        ge / gf
    )
    .unwrap();
    let (fit_s, sigma_s, gmres) = uncertainty()?;
    writeln!(
        table,
        "| fixtures/fit: σ from {} samples (`run --uncertainty {}`), median of {REPEATS} | {fit_s:.2} (the fit) | {sigma_s:.2} beyond it ({gmres:.0} GMRES iterations) | {:.1}× |",
        UncertaintyParams::default().samples,
        UncertaintyParams::default().samples,
        sigma_s / fit_s
    )
    .unwrap();
    writeln!(
        table,
        "\nfixtures/fit ({} nodes), {} threads; `cargo xtask bench fit`.",
        fit.run().prepared.mesh.nodes.len(),
        rayon::current_num_threads()
    )
    .unwrap();
    print!("{table}");
    replace_block(&root().join("docs/benchmarks.md"), "fit", &table)?;
    println!("wrote docs/benchmarks.md (fit)");
    Ok(())
}
