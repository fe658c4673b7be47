//! `cargo xtask bench solver`: speed of the TLED kernels and of DR against Newton.
//!
//! Run optimised: from a debug build, `cargo xtask bench` re-runs itself from a release build.
//!
//! 1. ns per element-step of `Model::internal_forces_into` (the SIMD kernels) and of the old
//!    scalar kernels (`Model::internal_forces_scalar_into`, measured alternately in the same
//!    run) for T4, T4ANP and H8 on meshes of ≥ 50 000 elements (jittered structured cubes),
//!    in explicit rayon pools of 1 and 2 threads, with the new/old ratios and the 2-thread
//!    speed-up.
//! 2. DR steps and wall time against the Newton reference on a ~10 000-node T4 cube (bottom
//!    clamped, top pushed down by 20% of the height), with their max nodal difference.
//!
//! `BS_BENCH_N=n` replaces the T4 mesh by `n³` cells and runs the kernel table only (for
//! quick comparisons, e.g. a cache-resident mesh with `n = 6`).

use std::time::{Duration, Instant};

use bs_dr::{
    DrParams, DynamicRelaxation, Loads, Model, ModelOptions, Newton, NewtonParams, NoContact,
    Solid, TetFormulation,
};
use bs_material::Material;
use bs_mesh::{Mesh, Vector3};

use super::page::{Page, say};

/// Unit cube of `n³` cells, interior nodes jittered by up to 0.2 h; hexes, or 6 tets per
/// cell (Kuhn split, conforming).
fn cube(n: usize, tets: bool) -> Mesh {
    bs_mesh::structured::jittered_box_mesh(n, 1.0, tets, 0.2, 1)
}

fn model(mesh: &Mesh, tet: TetFormulation) -> Model {
    let material = Material::neo_hookean(3000.0, 0.49).expect("valid material");
    Model::uniform(
        mesh,
        Solid { material, density: 1000.0 },
        ModelOptions { tet, ..Default::default() },
    )
    .expect("valid model")
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool")
}

/// Best-of-5 times per force evaluation of the SIMD kernels (`internal_forces_into`) and of
/// the old scalar kernels (`internal_forces_scalar_into`), measured alternately in the same
/// pool (each sample long enough to be ≥ 0.2 s), so that the ratio survives a noisy machine.
fn time_forces(model: &Model, u: &[Vector3<f64>], threads: usize) -> (Duration, Duration) {
    pool(threads).install(|| {
        let mut ws = model.workspace();
        let mut rws = model.reference_workspace();
        let mut f = vec![Vector3::zeros(); model.node_count()];
        let mut new = || model.internal_forces_into(u, &mut ws, &mut f).expect("no inversion");
        let mut g = vec![Vector3::zeros(); model.node_count()];
        let mut old =
            || model.internal_forces_scalar_into(u, &mut rws, &mut g).expect("no inversion");
        new();
        old();
        let t = Instant::now();
        old();
        let once = t.elapsed().as_secs_f64().max(1e-6);
        let reps = ((0.2 / once).ceil() as usize).max(3);
        let (mut best_new, mut best_old) = (Duration::MAX, Duration::MAX);
        for _ in 0..5 {
            let t = Instant::now();
            for _ in 0..reps {
                old();
            }
            best_old = best_old.min(t.elapsed() / reps as u32);
            let t = Instant::now();
            for _ in 0..4 * reps {
                new();
            }
            best_new = best_new.min(t.elapsed() / (4 * reps) as u32);
        }
        (best_new, best_old)
    })
}

/// Runs the benchmark, prints the tables and writes them into docs/benchmarks.md (not for
/// `BS_BENCH_N`).
pub fn run() -> Result<(), String> {
    let mut page = Page::new("solver");
    say!(page, "brainshift solver benchmark (Neo-Hookean E = 3000, nu = 0.49; best of 5)");
    say!(page, "NOTE: shared 2-core machine, numbers are noisy; compare the ratios.");
    say!(
        page,
        "new = SIMD kernels ({} lanes), old = scalar kernels, both measured in this run.\n",
        if bs_dr::has_avx2_fma() { "AVX2/FMA" } else { "portable" }
    );
    say!(
        page,
        "{:<7} {:>7} {:>7} | {:>8} {:>8} {:>6} | {:>8} {:>8} {:>6} | {:>7}",
        "kernel",
        "elems",
        "nodes",
        "old 1t",
        "new 1t",
        "ratio",
        "old 2t",
        "new 2t",
        "ratio",
        "new 2/1"
    );
    say!(page, "{:<23} | {:^24} | {:^24} |", "", "ns per element-step", "ns per element-step");
    let nt4: usize = std::env::var("BS_BENCH_N").ok().and_then(|s| s.parse().ok()).unwrap_or(21);
    let t4_mesh = cube(nt4, true); // 55 566 tets, 10 648 nodes
    let h8_mesh = cube(37, false); // 50 653 hexes
    for (name, mesh, tet) in [
        ("T4", &t4_mesh, TetFormulation::T4),
        ("T4ANP", &t4_mesh, TetFormulation::T4Anp),
        ("H8", &h8_mesh, TetFormulation::T4),
    ] {
        let m = model(mesh, tet);
        let u: Vec<Vector3<f64>> = mesh
            .nodes
            .iter()
            .map(|p| Vector3::new(0.02 * (3.0 * p.z).sin(), 0.01 * p.x * p.y, -0.03 * p.z * p.z))
            .collect();
        let ne = mesh.elements.len() as f64;
        let ns = |d: Duration| d.as_secs_f64() * 1e9 / ne;
        let (n1, o1) = time_forces(&m, &u, 1);
        let (n2, o2) = time_forces(&m, &u, 2);
        let (n1, o1, n2, o2) = (ns(n1), ns(o1), ns(n2), ns(o2));
        say!(
            page,
            "{:<7} {:>7} {:>7} | {:>8.1} {:>8.1} {:>5.2}x | {:>8.1} {:>8.1} {:>5.2}x | {:>6.2}x",
            name,
            mesh.elements.len(),
            mesh.nodes.len(),
            o1,
            n1,
            o1 / n1,
            o2,
            n2,
            o2 / n2,
            n1 / n2
        );
    }

    if std::env::var("BS_BENCH_N").is_ok() {
        return Ok(());
    }
    dr_against_newton(&mut page, &t4_mesh)?;
    preconditioners(&mut page)?;
    page.write("cargo xtask bench solver")
}

/// Two levels against the multilevel hierarchy on the MNI152 demo and, when `bench e2e`
/// has meshed it, the 852k-tet brain (`crate::precond`); then both in whole solves.
fn preconditioners(page: &mut Page) -> Result<(), String> {
    let bandwidth = crate::precond::stream_bandwidth();
    say!(
        page,
        "\nPreconditioner: K0 x = b to 1e-8 (GMRES, restart 40), one cycle (best of 5 x 10); \
         memory bandwidth (triad, 3 x 32 MiB, 2 threads) {:.1} GB/s",
        bandwidth / 1e9
    );
    say!(
        page,
        "{:<16} {:>7} {:<22} {:>7} {:>6} {:>9} {:>9} {:>8} {:>7}",
        "mesh",
        "nodes",
        "levels (coarse unknowns)",
        "setup s",
        "GMRES",
        "ms/cycle",
        "MB/cycle",
        "GB/s",
        "floor"
    );
    let root = crate::util::root();
    let mut scenes = vec![("mni152 demo", root.join("fixtures/mni152/scene.toml"))];
    let large = root.join("target/bench-e2e/mni152-size3/scene.toml");
    if large.exists() {
        scenes.push(("mni152 852k", large));
    }
    for (name, scene) in &scenes {
        for levels in [2, bs_dr::MultilevelParams::default().max_levels] {
            let c = crate::precond::measure(scene, levels)?;
            let achieved = c.bytes as f64 / c.seconds;
            say!(
                page,
                "{:<16} {:>7} {:<22} {:>7.2} {:>6} {:>9.2} {:>9.1} {:>8.1} {:>6.2}x",
                name,
                c.nodes,
                format!("{levels}: {:?}", c.levels),
                c.setup,
                c.gmres,
                c.seconds * 1e3,
                c.bytes as f64 / 1e6,
                achieved / 1e9,
                bandwidth / achieved
            );
        }
    }
    say!(page, "floor: the cycle's time against its bytes moved at the measured bandwidth");
    say!(page, "\nWhole Newton-Krylov solves, two levels against the default hierarchy:");
    say!(
        page,
        "{:<26} {:>7} {:>8} {:>6} {:>8} | {:>7} {:>8} {:>6} {:>8}",
        "scene",
        "levels",
        "Newton",
        "GMRES",
        "solve s",
        "levels",
        "Newton",
        "GMRES",
        "solve s"
    );
    let mut solves = vec![
        ("mni152 demo", root.join("fixtures/mni152/scene.toml")),
        ("mni152 gravity", root.join("fixtures/mni152/scene-gravity.toml")),
    ];
    if scenes.len() > 1 {
        solves.push(scenes[1].clone());
    }
    for (name, scene) in &solves {
        let p = bs_scene::Prepared::load(scene).map_err(|e| e.to_string())?;
        let mut cells = Vec::new();
        for levels in [2, bs_dr::MultilevelParams::default().max_levels] {
            let v = crate::study::Variant { max_levels: Some(levels), ..Default::default() };
            let o = v.solve(&p).map_err(|e| format!("{name}: {e}"))?;
            cells.push(format!(
                "{levels:>7} {:>8} {:>6} {:>8.3}",
                o.steps, o.linear_iterations, o.solve_seconds
            ));
        }
        say!(page, "{:<26} {} | {}", name, cells[0], cells[1]);
    }
    Ok(())
}

/// DR against Newton on the 10 648-node T4 cube, top pushed down 20 %.
fn dr_against_newton(page: &mut Page, t4_mesh: &Mesh) -> Result<(), String> {
    // DR vs Newton on the 10 648-node T4 cube.
    let m = model(t4_mesh, TetFormulation::T4);
    let mut loads = Loads::new(t4_mesh.nodes.len());
    for (i, p) in t4_mesh.nodes.iter().enumerate() {
        if p.z.abs() < 1e-12 {
            loads.fix_node(i).map_err(|e| e.to_string())?;
        }
        if (p.z - 1.0).abs() < 1e-12 {
            loads.prescribe_node(i, Vector3::new(0.0, 0.0, -0.2)).map_err(|e| e.to_string())?;
        }
    }
    say!(
        page,
        "\nDR vs Newton: T4 cube, {} nodes, {} tets, top pushed 20% (2 threads)",
        t4_mesh.nodes.len(),
        t4_mesh.elements.len()
    );
    let (dr, newton) = pool(2).install(|| {
        let dr = DynamicRelaxation::new(DrParams::default()).solve(bs_dr::Problem::new(
            &m,
            &loads,
            &mut NoContact,
            &mut |_| {},
        ));
        let newton = Newton::new(NewtonParams { load_steps: 5, ..Default::default() })
            .solve(bs_dr::Problem::new(&m, &loads, &mut NoContact, &mut |_| {}));
        (dr, newton)
    });
    let dr = dr.map_err(|e| format!("DR: {e}"))?;
    let newton = newton.map_err(|e| format!("Newton: {e}"))?;
    let diff = dr
        .displacements
        .iter()
        .zip(&newton.displacements)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).amax()));
    say!(
        page,
        "DR:     {:>7} steps  {:>8.2} s  ({:.1} us/step, rho {:.5}, err {:.2e})",
        dr.report.steps,
        dr.report.elapsed.as_secs_f64(),
        dr.report.elapsed.as_secs_f64() * 1e6 / dr.report.steps as f64,
        dr.report.rho,
        dr.report.err
    );
    say!(
        page,
        "Newton: {:>7} iters  {:>8.2} s  ({} load steps, sparse Cholesky)",
        newton.report.iterations,
        newton.report.elapsed.as_secs_f64(),
        newton.report.load_steps
    );
    say!(
        page,
        "max nodal |u_DR - u_Newton| = {diff:.2e} (load 0.2, DR tolerance {:.1e}); wall-time ratio DR/Newton = {:.2}",
        dr.report.tolerance,
        dr.report.elapsed.as_secs_f64() / newton.report.elapsed.as_secs_f64()
    );
    Ok(())
}
