//! The brainshift program as a library: scene loading and checking, composition of the
//! solver and contact crates, runs, and [`study`] (one scene solved with variations, what
//! `cargo xtask validate|chart|stability` measure). The `brainshift` binary is a thin
//! command-line front end over these modules.

pub mod advice;
pub mod check;
pub mod compose;
pub mod gap;
pub mod inspect;
pub mod run;
pub mod scene;
pub mod study;

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
