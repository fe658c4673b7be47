//! `bs-fuzz` (run as `cargo xtask fuzz`): mutation fuzzing of every file reader and of the
//! scene parser.
//!
//! Real fixtures are mutated (`mutate.rs`) from the seeds of each reader (`seeds.rs`,
//! `reader.rs`) and each input is parsed in process on a worker thread (`worker.rs`,
//! `run.rs`):
//! * a panic is a finding (caught with `catch_unwind`);
//! * a parse that takes longer than `run::DEADLINE` is a finding (a hang);
//! * an allocation beyond `64 × input size + 256 MiB` fails: this program's global allocator
//!   is capped during each input (the `cap` crate), so an allocation sized by a count in the
//!   file aborts the process. Each input is first written to `target/fuzz/current.<ext>`,
//!   so an abort leaves it behind; the next run replays it and, if it crashes again, saves it
//!   as a finding before fuzzing.
//!
//! The allocator is why the fuzzer is its own binary: no benchmark or other tool runs under
//! it. Findings are saved as `fixtures/fuzz/<reader>-<n>.<ext>` (one per distinct panic
//! site); every file there is a regression test of its reader's crate
//! (`tests/fuzz_findings.rs` of bs-mesh and bs-scene). Built with the `fuzzing` profile
//! (optimised, overflow checks and debug assertions kept).

mod mutate;
mod reader;
mod run;
mod seeds;
mod worker;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use reader::Reader;
use run::{Options, run};

/// The allocator, capped during each input so that an allocation sized by a count in a file
/// fails (and aborts, leaving the input behind) instead of exhausting the machine. The
/// `unsafe` of the `GlobalAlloc` implementation is inside the `cap` crate.
#[global_allocator]
static ALLOC: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, usize::MAX);

/// The repository's root folder.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match fuzz(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("fuzz failed: {e}");
            ExitCode::FAILURE
        }
    }
}

fn fuzz(args: &[String]) -> Result<(), String> {
    let mut options = Options {
        seconds: 60.0,
        seed: 1,
        cap_memory: true,
        save_to: Some(root().join("fixtures/fuzz")),
        scratch: Some(root().join("target/fuzz")),
        quiet: false,
    };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match a.as_str() {
            "--seconds" => {
                options.seconds = value("--seconds")?
                    .parse()
                    .map_err(|_| "--seconds takes a number of seconds".to_string())?
            }
            // Parse one saved input with the allocator capped (how an aborted run's last
            // input is checked): exits normally unless the input crashes the process.
            "--replay" => {
                let path = PathBuf::from(value("--replay")?);
                let reader = Reader::of_path(&path)
                    .ok_or_else(|| format!("{}: no reader for this extension", path.display()))?;
                let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
                let limit = ALLOC.allocated() + bytes.len() * 64 + (256 << 20);
                let _ = ALLOC.set_limit(limit);
                let accepted = reader.parse(&bytes);
                let _ = ALLOC.set_limit(usize::MAX);
                println!("{}: {}", path.display(), if accepted { "accepted" } else { "refused" });
                return Ok(());
            }
            "--seed" => {
                options.seed =
                    value("--seed")?.parse().map_err(|_| "--seed takes an integer".to_string())?
            }
            other => return Err(format!("unknown argument '{other}'")),
        }
    }
    println!(
        "fuzzing every reader for {} s, seed {}; an input that aborts the process stays in \
         target/fuzz/current.<ext>",
        options.seconds, options.seed
    );
    let s = run(&options)?;
    let secs = s.elapsed.as_secs_f64().max(1e-9);
    println!(
        "\n{:<6} {:>10} {:>10} {:>9} {:>12}",
        "reader", "inputs", "accepted", "inputs/s", "ms/input"
    );
    for (r, (n, ok, t)) in &s.per_reader {
        let ms = t.as_secs_f64() * 1e3 / (*n).max(1) as f64;
        println!("{:<6} {n:>10} {ok:>10} {:>9.0} {ms:>12.3}", r.name(), *n as f64 / secs);
    }
    println!(
        "{:<6} {:>10} {:>10} {:>9.0}\n{} findings ({} failing inputs) in {secs:.0} s",
        "total",
        s.total(),
        s.per_reader.values().map(|v| v.1).sum::<u64>(),
        s.total() as f64 / secs,
        s.findings.len(),
        s.failing_inputs
    );
    for f in &s.findings {
        let at = f.saved.as_ref().map(|p| format!(" ({})", p.display()));
        println!("  {}: {}{}", f.reader.name(), f.what, at.unwrap_or_default());
    }
    if s.findings.is_empty() { Ok(()) } else { Err(format!("{} findings", s.findings.len())) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cap the fuzzer sets makes an oversized allocation fail (here a fallible one, which
    /// reports instead of aborting).
    #[test]
    fn the_capped_allocator_refuses_beyond_its_limit() {
        let limit = ALLOC.allocated() + (1 << 30);
        ALLOC.set_limit(limit).unwrap();
        let r = Vec::<u8>::new().try_reserve_exact(2 << 30);
        ALLOC.set_limit(usize::MAX).unwrap();
        assert!(r.is_err(), "a 2 GiB allocation passed a 1 GiB cap");
    }
}
