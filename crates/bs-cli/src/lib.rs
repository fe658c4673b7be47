//! The `brainshift` command-line program: one module per command, each a thin front end
//! (argument handling, progress, printing) over `bs-scene` (scenes, runs, checks) and
//! `bs-mesh` (`inspect`); `warp` and `field` apply a result to images through
//! `bs_register::registration`.

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
