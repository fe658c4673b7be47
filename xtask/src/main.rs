//! Project automation for brainshift, run as `cargo xtask <command>`.
//!
//! Commands:
//! * `deps`: checks the crate dependency graph against the layering rules of
//!   `docs/ARCHITECTURE.md` (also run as a test).
//! * `bench contact`: the paper's contact benchmark for every handler (release build),
//!   table written to `docs/contact-bench.md`.

mod bench_contact;
mod deps;

use std::process::ExitCode;

const HELP: &str = "\
cargo xtask <command>

Commands:
  deps            check the workspace crate graph against the layering rules
  bench contact   contact handlers on the paper's benchmark (writes docs/contact-bench.md)
  help            print this help
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
        Some("bench") if args.get(1).map(String::as_str) == Some("contact") => {
            match bench_contact::main() {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("{e}");
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
