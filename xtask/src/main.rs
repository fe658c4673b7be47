//! Project automation for brainshift, run as `cargo xtask <command>`; `cargo xtask help`
//! lists the commands (the one list is `flags::COMMANDS`).
//!
//! xtask is thin: `flags.rs` parses the arguments into the options bs-study's studies,
//! validation, charts and benchmarks take, and this file dispatches to them; `deps/` holds
//! the repository's own checks (crate layering, module cycles, bs-dr's layer order, unused
//! dependencies), also run as tests. The fuzzer is its own program (bs-fuzz, with its capped
//! allocator), which `fuzz` runs.
//!
//! Benchmarks, studies and validation always run optimised: from a debug build they re-run
//! themselves with `cargo run --release`.

mod deps;
mod flags;

use std::process::ExitCode;

use bs_study::{bench, chart, fit, ghost, reference, stability, validate};
use flags::{Bench, Build, Task};

/// Runs `cargo run --profile <profile> --package <package> -- <args>`.
fn cargo_run(profile: &str, package: &str, args: &[String]) -> ExitCode {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = std::process::Command::new(cargo)
        .args(["run", "--profile", profile, "--quiet", "--package", package, "--"])
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

fn report(result: Result<(), String>, what: &str) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{what} failed: {e}");
            ExitCode::FAILURE
        }
    }
}

fn bench(b: &Bench) -> Result<(), String> {
    match b {
        Bench::Solver => bench::solver::run(),
        Bench::Contact => bench::contact::run(),
        Bench::E2e(o) => bench::e2e::run(o),
        Bench::E2eChild { case, solver, out } => bench::e2e::run_one(case, solver, out),
        Bench::Mesh => bench::mesh::run(),
        Bench::Warp => bench::warp::run(),
        Bench::Update(scene) => bench::update::run(scene.as_deref()),
        Bench::Fit => bench::fit::run(),
        Bench::Serve => bench::serve::run(),
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let task = match flags::parse(&args) {
        Ok(task) => task,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    let build = flags::command(&args).map_or(Build::Any, |c| c.build);
    if build == Build::Release && cfg!(debug_assertions) {
        return cargo_run("release", "xtask", &args);
    }
    match task {
        Task::Deps => match deps::run() {
            Ok(summary) => {
                println!("{summary}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("{e}");
                ExitCode::FAILURE
            }
        },
        Task::Bench(b) => report(bench(&b), &args[..2].join(" ")),
        Task::Ghost => report(ghost::main(), "ghost"),
        Task::Fit(o) => report(fit::main(&o), "fit"),
        Task::Validate(o) => report(validate::main(&o), "validate"),
        Task::Chart(o) => report(chart::main(&o), "chart"),
        Task::Stability(o) => report(stability::main(&o), "stability"),
        // Optimised, with overflow checks and debug assertions kept (Cargo.toml).
        Task::Fuzz(a) => cargo_run("fuzzing", "bs-fuzz", &a),
        Task::Reference(o) => report(reference::run(&o), "reference"),
        Task::Help => {
            print!("{}", flags::help());
            ExitCode::SUCCESS
        }
    }
}
