//! `brainshift`: brain shift computation for image-guided neurosurgery.

mod check;
mod inspect;
mod scene;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Computes brain shift with a Total Lagrangian explicit finite-element model solved by
/// Dynamic Relaxation, with kinematic brain–skull contact.
#[derive(Debug, Parser)]
#[command(name = "brainshift", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Reads a mesh file and prints what it holds: counts, sets, bounding box, element
    /// quality, surface closedness and orientation. Exits non-zero if the mesh is unusable.
    ///
    /// Formats: .inp (Abaqus), .msh (Gmsh 2.2/4.1 ASCII), .vtk, .vtu (volume);
    /// .stl, .obj, .off (surface).
    Inspect {
        /// The mesh file.
        file: PathBuf,
        /// Print the report as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Validates a scene file and everything it refers to without running it: mesh validity,
    /// element and node sets, materials, boundary conditions, unit sanity and the skull
    /// surface (closed, manifold, outward). Exits non-zero naming the first problem.
    Check {
        /// The scene file (TOML).
        scene: PathBuf,
    },
}

/// Writes `text` to standard output. A closed pipe (`brainshift inspect x | head`) is not an
/// error worth a message: the reader has what it wanted, so the program ends quietly.
pub(crate) fn emit(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: cannot write to standard output: {e}");
        std::process::exit(1);
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result: Result<ExitCode, Box<dyn std::error::Error>> = match cli.command {
        Command::Inspect { file, json } => inspect::run(&file, json).map_err(Into::into),
        Command::Check { scene } => check::run(&scene).map_err(Into::into),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
