//! `brainshift._native.serve(argv)`: the native OpenIGTLink server of bs-serve — the one
//! `brainshift serve` runs — started from Python (`python -m brainshift.serve`), its
//! arguments parsed by the same declaration as the binary's (`bs_serve::Command`). The GIL
//! is released while it serves; Ctrl-C (SIGINT) and SIGTERM stop it cleanly.

use clap::Parser;
use pyo3::prelude::*;

/// Serves as `brainshift serve ARGS...` does until Ctrl-C; returns the exit code (0 when
/// stopped, 1 for an error before listening, printed on stderr; 2 for bad arguments, with
/// clap's message; help and version print and return 0).
#[pyfunction]
pub(crate) fn serve(py: Python<'_>, argv: Vec<String>) -> i32 {
    let args = std::iter::once("brainshift serve".to_string()).chain(argv);
    let command = match bs_serve::Command::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return e.exit_code();
        }
    };
    py.detach(|| match bs_serve::run(&command.options, bs_serve::Log::stdout()) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            1
        }
    })
}
