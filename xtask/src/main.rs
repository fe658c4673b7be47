//! Project automation for brainshift, run as `cargo xtask <command>`.
//!
//! Commands:
//! * `deps`: checks the crate dependency graph against the layering rules of
//!   `docs/ARCHITECTURE.md` (also run as a test).
//! * `bench solver`: TLED kernel ns per element-step (1 vs 2 threads) and DR vs Newton
//!   wall time (always in release: re-runs itself with `cargo run --release`).

mod bench_solver;
mod deps;

use std::process::ExitCode;

const HELP: &str = "\
cargo xtask <command>

Commands:
  deps     check the workspace crate graph against the layering rules
  bench solver   kernel ns/element-step (1 vs 2 threads), DR vs Newton (release)
  help     print this help
";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("deps") => match deps::check_workspace() {
            Ok(edges) => {
                println!("crate graph OK ({edges} workspace edges checked)");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("{e}");
                ExitCode::FAILURE
            }
        },
        Some("bench") if args.get(1).map(String::as_str) == Some("solver") => {
            if cfg!(debug_assertions) && !args.iter().any(|a| a == "--no-rebuild") {
                let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
                let status = std::process::Command::new(cargo)
                    .args(["run", "--release", "--quiet", "--package", "xtask", "--"])
                    .args(["bench", "solver", "--no-rebuild"])
                    .status();
                return match status {
                    Ok(s) if s.success() => ExitCode::SUCCESS,
                    Ok(_) => ExitCode::FAILURE,
                    Err(e) => {
                        eprintln!("could not run cargo: {e}");
                        ExitCode::FAILURE
                    }
                };
            }
            match bench_solver::run() {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("bench solver failed: {e}");
                    ExitCode::FAILURE
                }
            }
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
