//! One fuzzing run: every reader in turn, each input mutated from its seeds, parsed on the
//! worker thread against a deadline, its findings (one per panic site or hang per reader)
//! saved; an input left behind by a run that aborted is replayed and saved first.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::mutate::{Rng, mutate_once};
use crate::reader::Reader;
use crate::seeds::seeds;
use crate::worker::{Outcome, PanicSlot, Worker, install_hook};

/// A parse taking longer than this is a hang.
pub const DEADLINE: Duration = Duration::from_secs(5);

/// Options of one fuzzing run.
#[derive(Debug, Clone)]
pub struct Options {
    pub seconds: f64,
    pub seed: u64,
    /// Cap the allocator during each input (off in the unit test, which shares its process
    /// with other tests).
    pub cap_memory: bool,
    /// Where findings are saved (none: only reported).
    pub save_to: Option<PathBuf>,
    /// Where the current input is written before it is parsed (none: not written).
    pub scratch: Option<PathBuf>,
    pub quiet: bool,
}

/// A panic or hang with the input that caused it.
#[derive(Debug, Clone)]
pub struct Finding {
    pub reader: Reader,
    pub what: String,
    pub saved: Option<PathBuf>,
}

/// What a run did.
#[derive(Debug, Default)]
pub struct Summary {
    /// Inputs tried and accepted (parsed `Ok`) per reader, and the time spent parsing.
    pub per_reader: BTreeMap<Reader, (u64, u64, Duration)>,
    /// Distinct findings (one per panic site or hang per reader).
    pub findings: Vec<Finding>,
    /// All inputs that panicked or hung, duplicates included.
    pub failing_inputs: u64,
    pub elapsed: Duration,
}

impl Summary {
    pub fn total(&self) -> u64 {
        self.per_reader.values().map(|v| v.0).sum()
    }
}

/// The site of a finding, to keep one input per distinct bug.
fn site(what: &str) -> String {
    what.rsplit_once(" at ").map(|(_, at)| at.to_string()).unwrap_or_else(|| what.to_string())
}

/// Saves `input` as `<dir>/<reader>-<n>.<ext>` with the first free `n`.
pub fn save_finding(dir: &Path, reader: Reader, input: &[u8]) -> Result<PathBuf, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for n in 1.. {
        let p = dir.join(format!("{}-{n}.{}", reader.name(), reader.extension()));
        if !p.exists() {
            std::fs::write(&p, input).map_err(|e| format!("{}: {e}", p.display()))?;
            return Ok(p);
        }
    }
    unreachable!("the loop returns")
}

/// An input left in `scratch` by a run that aborted (the marker `running` is removed when a
/// run ends normally; the input is the newest `current.<ext>`): saved as a finding.
fn recover_aborted(scratch: &Path, save_to: Option<&Path>) -> Result<Option<Finding>, String> {
    let marker = scratch.join("running");
    if !marker.exists() {
        return Ok(None);
    }
    std::fs::remove_file(&marker).map_err(|e| format!("{}: {e}", marker.display()))?;
    let newest = Reader::ALL
        .into_iter()
        .map(|r| (r, scratch.join(format!("current.{}", r.extension()))))
        .filter_map(|(r, p)| Some((std::fs::metadata(&p).ok()?.modified().ok()?, r, p)))
        .max_by_key(|(t, ..)| *t);
    let Some((_, reader, current)) = newest else { return Ok(None) };
    // The run may also have been interrupted (Ctrl-C): replay the input in a child process,
    // which only a real crash ends abnormally.
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let replay = std::process::Command::new(exe)
        .arg("--replay")
        .arg(&current)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .map_err(|e| format!("replaying {}: {e}", current.display()))?;
    if replay.success() {
        return Ok(None);
    }
    let input = std::fs::read(&current).map_err(|e| format!("{}: {e}", current.display()))?;
    let saved = save_to.map(|d| save_finding(d, reader, &input)).transpose()?;
    Ok(Some(Finding {
        reader,
        what: format!(
            "the previous run aborted on this input ({replay}: allocation failure or stack \
             overflow)"
        ),
        saved,
    }))
}

/// Fuzzes every reader in turn until `options.seconds` have passed.
pub fn run(options: &Options) -> Result<Summary, String> {
    let seeds = seeds()?;
    let mut summary = Summary::default();
    if let Some(scratch) = &options.scratch {
        std::fs::create_dir_all(scratch).map_err(|e| format!("{}: {e}", scratch.display()))?;
        if let Some(f) = recover_aborted(scratch, options.save_to.as_deref())? {
            summary.failing_inputs += 1;
            summary.findings.push(f);
        }
    }
    let slot: PanicSlot = Arc::default();
    install_hook(slot.clone());
    let mut worker = Worker::start(options.cap_memory, slot.clone());
    let mut rng = Rng::new(options.seed);
    let mut sites: BTreeSet<(Reader, String)> = BTreeSet::new();
    let start = Instant::now();
    let budget = Duration::from_secs_f64(options.seconds.max(0.0));
    let mut last_report = Instant::now();
    'outer: while start.elapsed() < budget {
        for reader in Reader::ALL {
            let pool = &seeds[&reader];
            let mut input = rng.pick(pool).clone();
            let other = rng.pick(pool).clone();
            for _ in 0..=rng.below(4) {
                mutate_once(&mut rng, &mut input, &other);
            }
            if let Some(scratch) = &options.scratch {
                let cur = scratch.join(format!("current.{}", reader.extension()));
                std::fs::write(&cur, &input).map_err(|e| format!("{}: {e}", cur.display()))?;
            }
            let t0 = Instant::now();
            worker.send.send((reader, input.clone())).map_err(|_| "the worker thread died")?;
            let stats = summary.per_reader.entry(reader).or_default();
            stats.0 += 1;
            let what = match worker.recv.recv_timeout(DEADLINE) {
                Ok(Outcome::Parsed(ok)) => {
                    stats.1 += u64::from(ok);
                    stats.2 += t0.elapsed();
                    None
                }
                Ok(Outcome::Panicked(what)) => Some(what),
                Err(_) => Some(format!("no answer within {} s (a hang)", DEADLINE.as_secs())),
            };
            if let Some(what) = what {
                summary.failing_inputs += 1;
                let hang = what.contains("a hang");
                if sites.insert((reader, site(&what))) {
                    let saved = match &options.save_to {
                        Some(d) => Some(save_finding(d, reader, &input)?),
                        None => None,
                    };
                    if !options.quiet {
                        let at = saved.as_ref().map(|p| format!(" -> {}", p.display()));
                        println!("FINDING {}: {what}{}", reader.name(), at.unwrap_or_default());
                    }
                    summary.findings.push(Finding { reader, what, saved });
                }
                if hang {
                    // The stuck thread cannot be stopped; carry on with a fresh one.
                    worker = Worker::start(options.cap_memory, slot.clone());
                }
            }
            if start.elapsed() >= budget {
                break 'outer;
            }
        }
        if !options.quiet && last_report.elapsed() >= Duration::from_secs(30) {
            last_report = Instant::now();
            println!(
                "{:>5.0} s: {} inputs, {} findings",
                start.elapsed().as_secs_f64(),
                summary.total(),
                summary.findings.len()
            );
        }
    }
    summary.elapsed = start.elapsed();
    if let Some(scratch) = &options.scratch {
        let _ = std::fs::remove_file(scratch.join("running"));
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two seconds of fuzzing with a fixed seed find nothing.
    #[test]
    fn two_seconds_of_fuzzing_find_nothing() {
        let options = Options {
            seconds: 2.0,
            seed: 7,
            cap_memory: false,
            save_to: None,
            scratch: None,
            quiet: true,
        };
        let s = run(&options).unwrap();
        for r in Reader::ALL {
            assert!(s.per_reader.get(&r).is_some_and(|v| v.0 > 0), "{} never ran", r.name());
        }
        let found: Vec<_> = s.findings.iter().map(|f| (f.reader.name(), &f.what)).collect();
        assert!(found.is_empty(), "{found:?}");
    }
}
