//! `cargo xtask bench e2e`: the whole brain-shift computation, the paper's solver (Dynamic
//! Relaxation, the baseline) against the default (Newton–Krylov), on every contact fixture.
//!
//! Each case and solver runs in a child process of this program (`bench e2e --one CASE
//! SOLVER OUT`), so that each reports its own peak memory; the children run one after the
//! other, so the ratios compare runs of the same session on the same machine. Per run:
//! * preparation: what depends only on mesh, materials and skull (model precomputation,
//!   contact search structures, the Newton–Krylov preconditioner);
//! * solve: from known displacements to a converged, checked result (solver and the final
//!   contact check);
//! * iterations (DR steps or Newton iterations), force evaluations, GMRES iterations;
//! * mean and max nodal distance to the stored CalculiX K = 10 reference (on the meshes it
//!   was computed on; on the other MNI152 densities the reference is carried over by
//!   interpolation, so that column also holds the mesh-to-mesh difference);
//! * largest penetration of the written result, peak resident memory;
//! * and, per case, the speed-up of the solve against the baseline and the difference
//!   between the two answers.
//!
//! A last case, the MNI152 brain meshed at 3 mm by the mesher (`brainshift mesh
//! fixtures/mni152/mask.nii.gz --size 3 --craniotomy`: 852k tetrahedra, 152k nodes; the scene
//! is written once into `target/bench-e2e/`), runs Newton–Krylov only (DR would take tens of
//! minutes there) and has no CalculiX column (its craniotomy is the mesher's, not the
//! fixture's). It measures how the solve grows with the mesh: its solve time and GMRES
//! iterations as multiples of the default mesh's, same run.
//!
//! A second table runs the loads other than the push, Newton–Krylov against the demo push's
//! solve of the same run: the MNI152 brain under gravity with the fluid drained
//! (`scene-gravity.toml`) and hanging (`scene-hanging.toml`), the demo at ν = 0.499, and the
//! paper's 40 mm push of the hexahedral ellipsoid by both solvers.
//!
//! The tables are printed and written into `docs/benchmarks.md` between their `e2e` and
//! `e2e-loads` markers.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::study::{Variant, difference};
use bs_mesh::{TetLocator, Vector3, transfer};
use bs_scene::Prepared;
use bs_scene::scene::SolverKind;

use crate::calculix::{field, read_reference};
use crate::util::{replace_block, root};

/// The cases: name, scene, and the scene whose mesh the CalculiX reference was computed on.
const CASES: [(&str, &str, &str); 5] = [
    ("sphere-shell", "fixtures/sphere-shell/scene.toml", "sphere-shell"),
    ("ellipsoid (coarse)", "fixtures/ellipsoid/scene.toml", "ellipsoid"),
    ("mni152 coarse", "fixtures/mni152/scene-coarse.toml", "mni152"),
    ("mni152 default", "fixtures/mni152/scene.toml", "mni152"),
    ("mni152 fine", "fixtures/mni152/scene-fine.toml", "mni152"),
];

/// The loads other than the push (see the module documentation): name, scene, solvers, and
/// Poisson's ratio of every region when it differs from the scene's.
const LOADS: [(&str, &str, &[&str], Option<f64>); 4] = [
    ("mni152 gravity", "fixtures/mni152/scene-gravity.toml", &["newton-krylov"], None),
    ("mni152 hanging", "fixtures/mni152/scene-hanging.toml", &["newton-krylov"], None),
    ("mni152 push, nu = 0.499", "fixtures/mni152/scene.toml", &["newton-krylov"], Some(0.499)),
    (
        "ellipsoid hex 40 mm",
        "fixtures/ellipsoid/scene-40mm-dr.toml",
        &["dr", "newton-krylov"],
        None,
    ),
];

/// The generated case (see the module documentation): name and element size (mm).
const LARGE: (&str, f64) = ("mni152 852k (mesher, 3 mm)", 3.0);

/// The scene of [`LARGE`], meshed on first use.
fn large_scene() -> Result<PathBuf, String> {
    let dir = root().join("target/bench-e2e/mni152-size3");
    let scene = dir.join("scene.toml");
    if !scene.exists() {
        let params = bs_scene::mesh_scene::MeshParams { size: LARGE.1, ..Default::default() };
        let mask = root().join("fixtures/mni152/mask.nii.gz");
        bs_scene::mesh_scene::mesh_to_scene(&mask, &dir, &params, true)
            .map_err(|e| format!("meshing {}: {e}", mask.display()))?;
    }
    Ok(scene)
}

/// One run, as a child reports it.
#[derive(Debug, Clone)]
struct Run {
    prepare: f64,
    solve: f64,
    iterations: usize,
    forces: usize,
    linear: usize,
    ccx_mean: f64,
    ccx_max: f64,
    penetration: f64,
    peak_mib: f64,
    nodes: usize,
    elements: usize,
    displacements: PathBuf,
}

fn solver_kind(name: &str) -> Result<SolverKind, String> {
    match name {
        "dr" => Ok(SolverKind::Dr),
        "newton-krylov" => Ok(SolverKind::NewtonKrylov),
        other => Err(format!("unknown solver {other}")),
    }
}

/// Peak resident memory of this process (MiB), from `/proc/self/status`.
fn peak_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// The CalculiX K = 10 field on `p`'s nodes: read on its own mesh, interpolated otherwise.
fn ccx_field(p: &Prepared, ccx_case: &str) -> Result<Option<Vec<Vector3<f64>>>, String> {
    let dir = root().join("fixtures").join(ccx_case).join("reference");
    let Some(r) = read_reference(&dir, "ccx-k10")? else { return Ok(None) };
    let own = root().join("fixtures").join(ccx_case).join("scene.toml");
    let own = Prepared::load(&own).map_err(|e| e.to_string())?;
    let u = field(&own, &r, ccx_case)?;
    if own.mesh.nodes.len() == p.mesh.nodes.len() && own.mesh.nodes == p.mesh.nodes {
        return Ok(Some(u));
    }
    let locator = TetLocator::new(&own.mesh).map_err(|e| e.to_string())?;
    Ok(Some(transfer(&locator, &u, &p.mesh.nodes)))
}

/// The child: one case with one solver; prints one line of key=value pairs.
pub fn run_one(case: &str, solver: &str, out: &Path) -> Result<(), String> {
    let load = LOADS.iter().find(|l| l.0 == case);
    let (scene, ccx_case) = if case == LARGE.0 {
        (large_scene()?, None)
    } else if let Some(l) = load {
        (root().join(l.1), None)
    } else {
        let (_, scene, ccx) =
            CASES.iter().find(|c| c.0 == case).ok_or_else(|| format!("unknown case {case}"))?;
        (root().join(scene), Some(*ccx))
    };
    let p = Prepared::load(&scene).map_err(|e| e.to_string())?;
    let v = Variant {
        solver: Some(solver_kind(solver)?),
        poisson_ratio: load.and_then(|l| l.3),
        ..Variant::default()
    };
    let o = v.solve(&p).map_err(|e| format!("{case} {solver}: {e}"))?;
    let reference = match ccx_case {
        Some(c) => ccx_field(&p, c)?,
        None => None,
    };
    let (ccx_mean, ccx_max) = match reference {
        Some(u) => difference(&o.displacements, &u, None),
        None => (f64::NAN, f64::NAN),
    };
    let mut csv = String::with_capacity(o.displacements.len() * 64);
    for d in &o.displacements {
        csv.push_str(&format!("{:?},{:?},{:?}\n", d.x, d.y, d.z));
    }
    std::fs::write(out, csv).map_err(|e| format!("{}: {e}", out.display()))?;
    println!(
        "result prepare={} solve={} iterations={} forces={} linear={} ccx_mean={} ccx_max={} \
         penetration={} peak_mib={} nodes={} elements={}",
        o.prepare_seconds,
        o.solve_seconds,
        o.steps,
        o.force_evaluations,
        o.linear_iterations,
        ccx_mean,
        ccx_max,
        o.max_penetration_after,
        peak_mib(),
        p.mesh.nodes.len(),
        p.mesh.elements.len()
    );
    Ok(())
}

/// Runs a child and parses its result line.
fn spawn(case: &str, solver: &str, out: &Path) -> Result<Run, String> {
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let output = Command::new(exe)
        .args(CHILD)
        .args([case, solver])
        .arg(out)
        .output()
        .map_err(|e| e.to_string())?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        return Err(format!(
            "{case} {solver} failed: {}{}",
            stdout,
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    let line = stdout
        .lines()
        .find(|l| l.starts_with("result "))
        .ok_or_else(|| format!("{case} {solver}: no result line in {stdout}"))?;
    let get = |key: &str| -> Result<f64, String> {
        line.split_whitespace()
            .find_map(|kv| kv.strip_prefix(&format!("{key}=")))
            .ok_or_else(|| format!("{case} {solver}: no {key}"))?
            .parse::<f64>()
            .map_err(|e| format!("{case} {solver}: {key}: {e}"))
    };
    Ok(Run {
        prepare: get("prepare")?,
        solve: get("solve")?,
        iterations: get("iterations")? as usize,
        forces: get("forces")? as usize,
        linear: get("linear")? as usize,
        ccx_mean: get("ccx_mean")?,
        ccx_max: get("ccx_max")?,
        penetration: get("penetration")?,
        peak_mib: get("peak_mib")?,
        nodes: get("nodes")? as usize,
        elements: get("elements")? as usize,
        displacements: out.to_path_buf(),
    })
}

fn read_field(path: &Path) -> Result<Vec<Vector3<f64>>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    text.lines()
        .map(|l| {
            let v: Vec<f64> = l
                .split(',')
                .map(|s| s.parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|e| e.to_string())?;
            Ok(Vector3::new(v[0], v[1], v[2]))
        })
        .collect()
}

/// What `cargo xtask bench e2e` runs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Options {
    /// One case alone (its name in the table), or every case.
    pub case: Option<String>,
    /// Runs per case and solver; the best is kept.
    pub repeat: usize,
}

/// The arguments that make the driving program run one case in a child process:
/// `<this program> bench e2e --one CASE SOLVER OUT` must call [`run_one`].
pub const CHILD: [&str; 3] = ["bench", "e2e", "--one"];

/// Runs the benchmark: every case (or `o.case`) by both solvers, the large mesh and the loads.
pub fn run(o: &Options) -> Result<(), String> {
    let (only, repeat) = (o.case.clone(), o.repeat.max(1));
    let tmp = std::env::temp_dir().join(format!("bs-bench-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).map_err(|e| e.to_string())?;
    println!(
        "end-to-end benchmark: each case solved by DR (baseline) and Newton-Krylov (default), \
         one child process per run, best of {repeat}; machine: {} threads available",
        rayon::current_num_threads()
    );
    let mut rows = Vec::new();
    for (case, _, _) in CASES {
        if only.as_deref().is_some_and(|o| o != case) {
            continue;
        }
        let mut best: Vec<Option<Run>> = vec![None, None];
        for r in 0..repeat {
            for (k, solver) in ["dr", "newton-krylov"].iter().enumerate() {
                let out = tmp.join(format!("{}-{solver}-{r}.csv", case.replace(' ', "_")));
                let run = spawn(case, solver, &out)?;
                println!(
                    "  {case:<20} {solver:<14} prepare {:>7.3} s  solve {:>8.3} s  {:>5} iterations",
                    run.prepare, run.solve, run.iterations
                );
                if best[k].as_ref().is_none_or(|b| run.solve < b.solve) {
                    best[k] = Some(run);
                }
            }
        }
        let (Some(dr), Some(nk)) = (best[0].take(), best[1].take()) else { continue };
        let (mean, max) =
            difference(&read_field(&dr.displacements)?, &read_field(&nk.displacements)?, None);
        rows.push((case, dr, nk, mean, max));
    }
    let mut table = markdown(&rows);
    if only.as_deref().is_none_or(|o| o == LARGE.0) {
        let out = tmp.join("large.csv");
        let large = spawn(LARGE.0, "newton-krylov", &out)?;
        println!(
            "  {:<20} {:<14} prepare {:>7.3} s  solve {:>8.3} s  {:>5} iterations",
            LARGE.0, "newton-krylov", large.prepare, large.solve, large.iterations
        );
        let default = rows.iter().find(|r| r.0 == "mni152 default").map(|r| &r.2);
        table.push_str(&large_row(&large, default));
    }
    let demo = rows.iter().find(|r| r.0 == "mni152 default").map(|r| r.2.clone());
    let loads = loads_table(only.as_deref(), demo.as_ref(), &tmp)?;
    println!("\n{table}\n{loads}");
    if only.is_none() {
        replace_block(&root().join("docs/benchmarks.md"), "e2e-loads", &loads)?;
        replace_block(&root().join("docs/benchmarks.md"), "e2e", &table)?;
        println!("wrote docs/benchmarks.md");
    }
    let _ = std::fs::remove_dir_all(&tmp);
    Ok(())
}

/// The loads other than the push ([`LOADS`]), each solve as a multiple of the demo push's
/// Newton–Krylov solve of the same run (`demo`), the hexahedral case's Newton–Krylov against
/// its Dynamic Relaxation.
fn loads_table(only: Option<&str>, demo: Option<&Run>, tmp: &Path) -> Result<String, String> {
    let mut s = String::from(
        "| load | nodes / elements | solver | Newton its / DR steps | GMRES its | force evals | solve s | × the demo push | × DR |\n\
         |---|---|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for (case, _, solvers, _) in LOADS {
        if only.is_some_and(|o| o != case) {
            continue;
        }
        let mut dr: Option<Run> = None;
        for solver in solvers {
            let out = tmp.join(format!("{}-{solver}.csv", case.replace([' ', ','], "_")));
            let r = spawn(case, solver, &out)?;
            println!(
                "  {case:<24} {solver:<14} solve {:>8.3} s  {:>5} iterations",
                r.solve, r.iterations
            );
            let vs_demo = demo.map_or_else(|| "—".into(), |d| format!("{:.2}×", r.solve / d.solve));
            let vs_dr =
                dr.as_ref().map_or_else(|| "—".into(), |d| format!("{:.2}×", r.solve / d.solve));
            s.push_str(&format!(
                "| {case} | {} / {} | {solver} | {} | {} | {} | {:.3} | {vs_demo} | {vs_dr} |\n",
                r.nodes, r.elements, r.iterations, r.linear, r.forces, r.solve
            ));
            if *solver == "dr" {
                dr = Some(r);
            }
        }
    }
    Ok(s)
}

/// The row of [`LARGE`] (Newton–Krylov only), with its solve time and GMRES iterations as
/// multiples of the default mesh's Newton–Krylov run of the same benchmark.
fn large_row(r: &Run, default: Option<&Run>) -> String {
    let growth = default.map_or_else(String::new, |d| {
        format!(
            "{:.1}× the default mesh's solve, {:.2}× its GMRES its ({:.1}× its elements)",
            r.solve / d.solve,
            r.linear as f64 / d.linear as f64,
            r.elements as f64 / d.elements as f64
        )
    });
    format!(
        "| {} | {} / {} | newton-krylov | {:.3} | {:.3} | {} | {} | {} | — | {:.1e} | {:.0} | {growth} | DR not run |\n",
        LARGE.0,
        r.nodes,
        r.elements,
        r.prepare,
        r.solve,
        r.iterations,
        r.forces,
        r.linear,
        r.penetration,
        r.peak_mib,
    )
}

fn markdown(rows: &[(&str, Run, Run, f64, f64)]) -> String {
    let mut s = String::from(
        "| case | nodes / elements | solver | prepare s | solve s | iterations | force evals | GMRES its | vs CalculiX K=10 mean / max mm | max penetration mm | peak MiB | solve speed-up | NK vs DR mean / max mm |\n\
         |---|---|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---|\n",
    );
    for (case, dr, nk, mean, max) in rows {
        for (name, r) in [("dr", dr), ("newton-krylov", nk)] {
            let nk_row = name == "newton-krylov";
            s.push_str(&format!(
                "| {case} | {} / {} | {name} | {:.3} | {:.3} | {} | {} | {} | {:.4} / {:.4} | {:.1e} | {:.0} | {} | {} |\n",
                r.nodes,
                r.elements,
                r.prepare,
                r.solve,
                r.iterations,
                r.forces,
                r.linear,
                r.ccx_mean,
                r.ccx_max,
                r.penetration,
                r.peak_mib,
                if nk_row { format!("{:.1}×", dr.solve / nk.solve) } else { "1×".into() },
                if nk_row { format!("{mean:.2e} / {max:.2e}") } else { String::new() },
            ));
        }
    }
    s
}
