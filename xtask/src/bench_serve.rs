//! `cargo xtask bench serve`: the latency of `brainshift serve` over OpenIGTLink, measured
//! by a client script of the Python package (`crates/bs-py/bench/serve_latency.py`): the
//! server is the Python package's, so the benchmark runs there. The interpreter is
//! BRAINSHIFT_PYTHON, else the CI venv (`target/py-venv`, made by `.ci/python.sh`), else
//! `python3`; it needs the `brainshift` package and pyigtl.

use bs_study::util::root;

pub fn main(args: &[String]) -> Result<(), String> {
    let root = root();
    let venv = root.join("target/py-venv/bin/python");
    let python = std::env::var("BRAINSHIFT_PYTHON").ok().unwrap_or_else(|| {
        if venv.exists() { venv.display().to_string() } else { "python3".into() }
    });
    let script = root.join("crates/bs-py/bench/serve_latency.py");
    println!("{python} {} {}", script.display(), args.join(" "));
    let status = std::process::Command::new(&python)
        .arg(&script)
        .args(args)
        .status()
        .map_err(|e| format!("could not start {python}: {e} (set BRAINSHIFT_PYTHON)"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!(
            "the client script failed ({status}); it needs `pip install ./crates/bs-py pyigtl` \
             in {python} (or BRAINSHIFT_PYTHON naming an interpreter that has them)"
        ))
    }
}
