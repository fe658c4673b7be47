//! Project automation for brainshift, run as `cargo xtask <command>`.
//!
//! Commands:
//! * `deps`: checks the crate dependency graph against the layering rules of
//!   `docs/ARCHITECTURE.md`, every crate's module graph for cycles and bs-dr's folders for
//!   their layer order (also run as tests).
//! * `bench solver`: TLED kernel ns per element-step (1 vs 2 threads) and DR vs Newton
//!   wall time.
//! * `bench contact`: the paper's contact benchmark for every handler, table written to
//!   `docs/contact-bench.md`.
//! * `bench warp`: the registration outputs (inverse map, warp, field) on the MNI152 T1
//!   template with the demo result, against reading the image and a naive per-voxel loop.
//! * `bench update`: a live session's warm-started updates of the MNI152 craniotomy at
//!   1..8 mm against cold solves of the same loads, and the warped T1 after each.
//! * `bench serve`: `brainshift serve` over OpenIGTLink, server and client in this process:
//!   a scan of fixtures/fit (its last byte → the WarpedImage's, against the solve and warp
//!   inside the server) and eight displacement sets of the MNI152 craniotomy.
//! * `bench e2e`: every contact fixture solved by DR and by Newton–Krylov in child
//!   processes: preparation and solve times, iterations, accuracy against CalculiX, peak
//!   memory, speed-up (table in `docs/benchmarks.md`).
//!
//! * `ghost`: the warped image where the brain moved away, and the field at the most
//!   displaced nodes, before and after the extension outside the brain.
//! * `bench mesh`: `brainshift mesh` at 4 mm on the MNI152 mask and an MNI-sized
//!   ellipsoid labelmap, 1 and 2 threads.
//!
//! * `validate`: every reference case in one table, written to `docs/validation.md`.
//! * `chart`: speed against accuracy over mesh density, element, DR tolerance, contact
//!   handler and solver, with CalculiX's points and the Pareto front (`docs/charts/`).
//! * `stability`: the stability map, one run per cell: converged, stopped by a guard, or
//!   failed silently (which must never happen).
//! * `fuzz`: mutation fuzzing of every file reader and the scene parser (panics, hangs,
//!   allocations sized by a count in the file); findings saved under `fixtures/fuzz/`.
//! * `reference`: CalculiX reference solutions of the contact fixtures, stored in
//!   `fixtures/<case>/reference/` (needs `ccx`).
//!
//! Benchmarks always run optimised: from a debug build they re-run themselves with
//! `cargo run --release`.

mod bench_contact;
mod bench_e2e;
mod bench_fit;
mod bench_mesh;
mod bench_serve;
mod bench_solver;
mod bench_update;
mod bench_warp;
mod deps;
mod fuzz;
mod page;

use std::process::ExitCode;

use bs_study::{chart, fit, ghost, reference, stability, validate};

/// The allocator, capped by `fuzz` during each input so that an allocation sized by a count
/// in a file fails (and aborts, leaving the input behind) instead of exhausting the machine.
/// The `unsafe` of the `GlobalAlloc` implementation is inside the `cap` crate.
#[global_allocator]
static ALLOC: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, usize::MAX);

const HELP: &str = "\
cargo xtask <command>

Commands:
  deps            check the workspace crate graph against the layering rules, every crate's
                  modules (all folders) for cycles, and bs-dr's folders for their layer order
  bench solver    kernel ns/element-step (1 vs 2 threads), DR vs Newton (release)
  bench contact   contact handlers on the paper's benchmark (writes docs/contact-bench.md)
  bench warp      warp and field of the MNI152 T1 template with the demo result: seconds,
                  against reading the image and a naive per-voxel TetLocator loop (release)
  bench e2e       [--case NAME] [--repeat N] every contact fixture solved by DR (baseline) and
                  Newton-Krylov (default): preparation, solve, iterations, accuracy against
                  CalculiX, peak memory, speed-up; then the 852k-tet MNI152 mesh (mesher,
                  3 mm; Newton-Krylov only) against the default mesh (writes docs/benchmarks.md)
  bench update    [--scene S] the MNI152 craniotomy measured at 1..8 mm: eight updates of a live session,
                  each warm from the last, against cold solves of the same loads; the warped
                  T1 after each; peak memory (release)
  bench serve     `brainshift serve` over OpenIGTLink (loopback, server and client in one
                  process): a scan of fixtures/fit sent three times and eight displacement
                  sets of the MNI152 craniotomy (1..8 mm); last byte sent -> warped image
                  received, against the solve and warp in the server (release)
  bench mesh      meshing a labelmap at 4 mm (MNI152 mask and an MNI-sized ellipsoid), 1 and 2
                  threads (release)
  ghost           the warped MNI152 T1 where the demo's brain moved away (the ghost of the old
                  cortex) and the exported field at the 50 most displaced nodes, for the identity
                  and the harmonic extension outside the brain
  fit             fixture: the measurement-fit fixture (fixtures/fit: a truth, one degraded scan);
                  study [--quick]: fits of degraded scans against the truth, imposing and no
                  correction; writes docs/fit.md's table and chart (release); gravity [--quick]:
                  scans of gravity-driven truths fitted with gravity known, off and estimated
  validate        [--quick] every reference case (closed forms, DR vs Newton, contact vs brute
                  force, DR + contact vs CalculiX); writes docs/validation.md (release)
  chart           [--case NAME] speed vs accuracy: mesh density, element, DR tolerance, contact
                  handler, DR vs Newton, CalculiX; writes docs/charts/ and docs/speed-accuracy.md
                  (release)
  stability       [--quick] the stability map: time step, Poisson ratio, hourglass control,
                  load until inversion, contact lists at sharp corners (writes docs/charts/)
  fuzz            --seconds N [--seed S] mutate the fixtures for every reader (.inp .msh .vtk .vtu
                  .stl .obj .off, scene.toml): panics, hangs (> 5 s) and allocations beyond
                  64 x input + 256 MiB are findings, saved as fixtures/fuzz/<reader>-<n>.<ext>;
                  exits non-zero on any finding (optimised with overflow checks: profile
                  `fuzzing`)
  reference       CalculiX reference solutions of the contact fixtures (needs ccx):
                  [--case NAME] [--deck-only] [--timeout S] [--memory-gib G] [--threads N] [--slope K] [--collect]
  help            print this help
";

/// Re-runs this xtask command from a release build; benchmarks of debug code mean nothing.
fn rerun_in_release(args: &[String]) -> ExitCode {
    rerun_with_profile("release", args)
}

/// Re-runs this xtask command built with the cargo profile `profile`.
fn rerun_with_profile(profile: &str, args: &[String]) -> ExitCode {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = std::process::Command::new(cargo)
        .args(["run", "--profile", profile, "--quiet", "--package", "xtask", "--"])
        .args(args)
        .status();
    match status {
        Ok(s) if s.success() => ExitCode::SUCCESS,
        Ok(_) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("could not run cargo: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Whether this executable was built with the cargo profile `profile` (it lives in
/// `target/<profile>/`; the `fuzzing` profile keeps debug assertions, so `cfg!` cannot tell).
fn built_with_profile(profile: &str) -> bool {
    std::env::current_exe()
        .ok()
        .and_then(|p| p.parent().and_then(|d| d.file_name()).map(|n| n == profile))
        .unwrap_or(false)
}

fn report(result: Result<(), String>, what: &str) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{what} failed: {e}");
            ExitCode::FAILURE
        }
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("deps") => match deps::run() {
            Ok(summary) => {
                println!("{summary}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("{e}");
                ExitCode::FAILURE
            }
        },
        Some("bench") if cfg!(debug_assertions) => rerun_in_release(&args),
        Some("bench") => match args.get(1).map(String::as_str) {
            Some("solver") => report(bench_solver::run(), "bench solver"),
            Some("contact") => report(bench_contact::main(), "bench contact"),
            Some("e2e") => report(bench_e2e::main(&args[2..]), "bench e2e"),
            Some("mesh") => report(bench_mesh::main(), "bench mesh"),
            Some("warp") => report(bench_warp::main(), "bench warp"),
            Some("update") => report(bench_update::main(&args[2..]), "bench update"),
            Some("fit") => report(bench_fit::main(), "bench fit"),
            Some("serve") => report(bench_serve::main(&args[2..]), "bench serve"),
            _ => {
                eprintln!(
                    "bench what? `cargo xtask bench solver`, `bench contact`, `bench e2e`, `bench mesh`, `bench warp`, `bench update`, `bench fit` or `bench serve`"
                );
                ExitCode::from(2)
            }
        },
        Some("validate") if cfg!(debug_assertions) => rerun_in_release(&args),
        Some("validate") => report(validate::main(&args[1..]), "validate"),
        Some("chart") if cfg!(debug_assertions) => rerun_in_release(&args),
        Some("chart") => report(chart::main(&args[1..]), "chart"),
        Some("stability") if cfg!(debug_assertions) => rerun_in_release(&args),
        Some("stability") => report(stability::main(&args[1..]), "stability"),
        // Optimised, with overflow checks and debug assertions kept (Cargo.toml).
        Some("fuzz") if cfg!(debug_assertions) && !built_with_profile("fuzzing") => {
            rerun_with_profile("fuzzing", &args)
        }
        Some("fuzz") => report(fuzz::main(&args[1..]), "fuzz"),
        Some("ghost") => report(ghost::main(), "ghost"),
        Some("fit") if cfg!(debug_assertions) => rerun_in_release(&args),
        Some("fit") => report(fit::main(&args[1..]), "fit"),
        Some("reference") => {
            report(reference::parse_args(&args[1..]).and_then(|o| reference::run(&o)), "reference")
        }
        None | Some("help" | "--help" | "-h") => {
            print!("{HELP}");
            ExitCode::SUCCESS
        }
        Some(other) => {
            eprintln!("unknown command '{other}'\n\n{HELP}");
            ExitCode::from(2)
        }
    }
}
