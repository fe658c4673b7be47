//! The `brainshift` command-line program: one module per command, each a thin front end
//! (argument handling, progress, printing) over `bs-scene` (scenes, runs, checks) and
//! `bs-mesh` (`inspect`); `warp` and `field` apply a result to images through
//! `bs_register::registration`.
//!
//! Files:
//! * `main.rs`: the clap command tree and the dispatch to the modules below;
//! * `inspect.rs`: `brainshift inspect FILE` (bs-mesh only);
//! * `check.rs`: `brainshift check SCENE` (`--json`, `--region-effect`);
//! * `run.rs`: `brainshift run SCENE`, with progress on the terminal;
//! * `uncertainty.rs`: `run --uncertainty N`, σ sampled after the solve and written;
//! * `demo.rs`: `brainshift demo`, the bundled MNI152 case (`--from-image`: from its
//!   labelmap);
//! * `gap.rs`: `brainshift gap`, the brain–skull gap of every boundary node or given points;
//! * `mesh.rs`: `brainshift mesh`, a labelmap to a scene folder;
//! * `warp.rs`: `brainshift warp`, with its `--preview` picture (bs-preview);
//! * `field.rs`: `brainshift field`, a displacement field on an image's grid;
//! * `serve.rs`: `brainshift serve`, bs-serve's server with bs-serve's options;
//! * `sweep.rs`: `brainshift sweep plan|run|collect|emit-slurm` over bs-sweep;
//! * `lib.rs` itself: `emit`, standard output that ends quietly on a closed pipe.
//!
//! Architecture invariant: a front end. It knows no materials, solver parameters or
//! composition: how a scene becomes a model is bs-scene's.

pub mod check;
pub mod demo;
pub mod field;
pub mod gap;
pub mod inspect;
pub mod mesh;
pub mod run;
pub mod serve;
pub mod sweep;
pub mod uncertainty;
pub mod warp;

/// Writes `text` to standard output. A closed pipe (`brainshift inspect x | head`) is not an
/// error worth a message: the reader has what it wanted, so the program ends quietly.
pub fn emit(text: &str) {
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
