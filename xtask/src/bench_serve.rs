//! `cargo xtask bench serve`: the latency of `brainshift serve` over OpenIGTLink, measured
//! by a client script of the Python package (`crates/bs-py/bench/serve_latency.py`): the
//! server is the Python package's, so the benchmark runs there. The interpreter is
//! BRAINSHIFT_PYTHON, else the CI venv (`target/py-venv`, made by `.ci/python.sh`), else
//! `python3`; it needs the `brainshift` package and pyigtl. The script's output is printed
//! as it comes and, for the default run, written into docs/benchmarks.md.

use std::io::{BufRead, BufReader};
use std::process::Stdio;

use bs_study::util::root;

use crate::page::{Page, say};

pub fn main(args: &[String]) -> Result<(), String> {
    let root = root();
    let venv = root.join("target/py-venv/bin/python");
    let python = std::env::var("BRAINSHIFT_PYTHON").ok().unwrap_or_else(|| {
        if venv.exists() { venv.display().to_string() } else { "python3".into() }
    });
    let script = root.join("crates/bs-py/bench/serve_latency.py");
    println!("{python} {} {}", script.display(), args.join(" "));
    let mut child = std::process::Command::new(&python)
        .arg(&script)
        .args(args)
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|e| format!("could not start {python}: {e} (set BRAINSHIFT_PYTHON)"))?;
    let mut page = Page::new("serve");
    if let Some(out) = child.stdout.take() {
        for line in BufReader::new(out).lines() {
            let line = line.map_err(|e| format!("reading the client's output: {e}"))?;
            // The server's own log is shown, not kept for the page.
            if line.starts_with("  server: ") {
                println!("{line}");
            } else {
                say!(page, "{line}");
            }
        }
    }
    let status = child.wait().map_err(|e| format!("waiting for {python}: {e}"))?;
    if status.success() && args.is_empty() {
        page.write("cargo xtask bench serve")
    } else if status.success() {
        Ok(())
    } else {
        Err(format!(
            "the client script failed ({status}); it needs `pip install ./crates/bs-py pyigtl` \
             in {python} (or BRAINSHIFT_PYTHON naming an interpreter that has them)"
        ))
    }
}
