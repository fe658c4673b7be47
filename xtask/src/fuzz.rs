//! `cargo xtask fuzz`: mutation fuzzing of every file reader and of the scene parser.
//!
//! Real fixtures are mutated (bit flips, byte insertions and deletions, truncation, splicing
//! two files, numbers replaced by hostile counts such as 2000000000, -1 or nan, binary words
//! overwritten with such counts, lines duplicated or dropped) and each input is parsed in
//! process on a worker thread:
//! * a panic is a finding (caught with `catch_unwind`);
//! * a parse that takes longer than [`DEADLINE`] is a finding (a hang);
//! * an allocation beyond `64 × input size + 256 MiB` fails: the global allocator of xtask is
//!   capped during each input (the `cap` crate), so an allocation sized by a count in the
//!   file aborts the process. Each input is first written to `target/fuzz/current.<ext>`,
//!   so an abort leaves it behind; the next `cargo xtask fuzz` replays it and, if it
//!   crashes again, saves it as a finding before fuzzing.
//!
//! Findings are saved as `fixtures/fuzz/<reader>-<n>.<ext>` (one per distinct panic site);
//! every file there is a regression test ([`tests::saved_findings_parse_without_panic`]).

use std::any::Any;
use std::collections::{BTreeMap, BTreeSet};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bs_mesh::io::{inp, msh, obj, off, stl, vtk, vtu};

use bs_study::util::root;

/// A parse taking longer than this is a hang.
pub const DEADLINE: Duration = Duration::from_secs(5);

/// Seed files larger than this are left out: they slow the fuzzer without covering more.
const MAX_SEED_BYTES: u64 = 100_000;

/// The readers under test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Reader {
    Inp,
    Msh,
    Vtk,
    Vtu,
    Stl,
    Obj,
    Off,
    Scene,
}

impl Reader {
    pub const ALL: [Reader; 8] = [
        Reader::Inp,
        Reader::Msh,
        Reader::Vtk,
        Reader::Vtu,
        Reader::Stl,
        Reader::Obj,
        Reader::Off,
        Reader::Scene,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Reader::Inp => "inp",
            Reader::Msh => "msh",
            Reader::Vtk => "vtk",
            Reader::Vtu => "vtu",
            Reader::Stl => "stl",
            Reader::Obj => "obj",
            Reader::Off => "off",
            Reader::Scene => "scene",
        }
    }

    pub fn extension(self) -> &'static str {
        match self {
            Reader::Scene => "toml",
            r => r.name(),
        }
    }

    /// The reader of a saved input, from its file name (`<reader>-<n>.<ext>`) or extension.
    pub fn of_path(path: &Path) -> Option<Reader> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Reader::ALL.into_iter().find(|r| r.extension() == ext)
    }

    /// Parses `bytes`; `Ok` or `Err` are both fine, only panics and hangs are findings.
    /// Returns whether the input was accepted.
    pub fn parse(self, bytes: &[u8]) -> bool {
        let file = PathBuf::from(format!("fuzz.{}", self.extension()));
        match self {
            Reader::Inp => inp::read(bytes, &file).is_ok(),
            Reader::Msh => msh::read(bytes, &file).is_ok(),
            Reader::Vtk => vtk::read(bytes, &file).is_ok(),
            Reader::Vtu => vtu::read(bytes, &file).is_ok(),
            Reader::Stl => stl::read(bytes, &file).is_ok(),
            Reader::Obj => obj::read(bytes, &file).is_ok(),
            Reader::Off => off::read(bytes, &file).is_ok(),
            Reader::Scene => bs_scene::scene::Scene::parse(&String::from_utf8_lossy(bytes)).is_ok(),
        }
    }
}

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

/// The workspace's one seeded generator: the same inputs for a seed.
pub type Rng = bs_mesh::rng::SplitMix64;

/// Numbers a hostile file puts where a count or coordinate belongs.
const HOSTILE_NUMBERS: [&str; 16] = [
    "2000000000",
    "-1",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "0",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "-2147483648",
    "9223372036854775807",
    "1e308",
    "-0",
    "99999999999999999999999",
    "1e-320",
];

/// Binary words a hostile file puts where a count or size belongs (little-endian).
const HOSTILE_WORDS: [u64; 8] = [
    2_000_000_000,
    u32::MAX as u64,
    0x8000_0000,
    0x7FFF_FFFF,
    u64::MAX,
    0x7FF8_0000_0000_0000, // NaN as f64
    0,
    1 << 40,
];

const INTERESTING_BYTES: &[u8] = b"\n\r \t-+.,0189eE*<>\"/=#$\0\xff";

/// One random mutation of `data`; `other` is another seed of the same reader (splicing).
pub fn mutate_once(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8]) {
    match rng.below(10) {
        // Bit flips.
        0 => {
            if !data.is_empty() {
                for _ in 0..=rng.below(4) {
                    let i = rng.below(data.len());
                    data[i] ^= 1 << rng.below(8);
                }
            }
        }
        // Insert bytes.
        1 => {
            let at = rng.below(data.len() + 1);
            let n = 1 + rng.below(8);
            for _ in 0..n {
                let b = if rng.below(2) == 0 {
                    *rng.pick(INTERESTING_BYTES)
                } else {
                    rng.next_u64() as u8
                };
                data.insert(at, b);
            }
        }
        // Delete a range.
        2 => {
            if !data.is_empty() {
                let at = rng.below(data.len());
                let longest = if rng.below(4) == 0 { 256 } else { 8 };
                let n = (1 + rng.below(longest)).min(data.len() - at);
                data.drain(at..at + n);
            }
        }
        // Truncate.
        3 => {
            let at = rng.below(data.len() + 1);
            data.truncate(at);
        }
        // Splice: a prefix of this file and a suffix of the other.
        4 => {
            if !other.is_empty() {
                let a = rng.below(data.len() + 1);
                let b = rng.below(other.len());
                data.truncate(a);
                data.extend_from_slice(&other[b..]);
            }
        }
        // Replace a number by a hostile one.
        5 | 6 => {
            let spans = number_spans(data);
            if !spans.is_empty() {
                let (a, b) = *rng.pick(&spans);
                let n = rng.pick(&HOSTILE_NUMBERS).as_bytes();
                data.splice(a..b, n.iter().copied());
            }
        }
        // Duplicate or drop a line.
        7 => {
            let starts = line_starts(data);
            let k = rng.below(starts.len());
            let (a, b) = (starts[k], starts.get(k + 1).copied().unwrap_or(data.len()));
            if rng.below(3) == 0 {
                data.drain(a..b);
            } else {
                let line = data[a..b].to_vec();
                let times = if rng.below(4) == 0 { 1 + rng.below(50) } else { 1 };
                for _ in 0..times {
                    data.splice(b..b, line.iter().copied());
                }
            }
        }
        // Overwrite a binary word with a hostile count.
        8 => {
            let width = if rng.below(2) == 0 { 4 } else { 8 };
            if data.len() >= width {
                let at = rng.below(data.len() - width + 1);
                let word = rng.pick(&HOSTILE_WORDS).to_le_bytes();
                data[at..at + width].copy_from_slice(&word[..width]);
            }
        }
        // Overwrite a byte with an interesting one.
        _ => {
            if !data.is_empty() {
                let i = rng.below(data.len());
                data[i] = *rng.pick(INTERESTING_BYTES);
            }
        }
    }
}

/// Byte ranges of the decimal numbers (digits with sign, point, exponent) in `data`.
fn number_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if data[i].is_ascii_digit() {
            let mut a = i;
            if a > 0 && data[a - 1] == b'-' {
                a -= 1;
            }
            while i < data.len() && (data[i].is_ascii_digit() || b".eE+-".contains(&data[i])) {
                i += 1;
            }
            spans.push((a, i));
        } else {
            i += 1;
        }
    }
    spans
}

fn line_starts(data: &[u8]) -> Vec<usize> {
    std::iter::once(0)
        .chain(data.iter().enumerate().filter(|&(_, &b)| b == b'\n').map(|(i, _)| i + 1))
        .filter(|&i| i < data.len() || i == 0)
        .collect()
}

/// The seed inputs of every reader: small fixtures, plus files the writers make (every VTU
/// encoding, ASCII and binary STL) so each code path has a valid start.
pub fn seeds() -> Result<BTreeMap<Reader, Vec<Vec<u8>>>, String> {
    let root = root();
    let mut seeds: BTreeMap<Reader, Vec<Vec<u8>>> = BTreeMap::new();
    let mut scan = |dir: &Path| -> Result<(), String> {
        let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
        paths.sort();
        for p in paths {
            let Some(reader) = Reader::of_path(&p) else { continue };
            let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(u64::MAX);
            if len <= MAX_SEED_BYTES {
                let bytes = std::fs::read(&p).map_err(|e| format!("{}: {e}", p.display()))?;
                seeds.entry(reader).or_default().push(bytes);
            }
        }
        Ok(())
    };
    for dir in ["basic", "readers", "bad", "cube", "ellipsoid", "sphere-shell", "mni152"] {
        scan(&root.join("fixtures").join(dir))?;
    }
    // Derived seeds: the writers' outputs of a small mesh and surface.
    let sphere =
        std::fs::read(root.join("fixtures/basic/sphere.vtu")).map_err(|e| e.to_string())?;
    let (mesh, fields) = vtu::read(&sphere, Path::new("sphere.vtu")).map_err(|e| e.to_string())?;
    let shell = std::fs::read(root.join("fixtures/basic/shell.off")).map_err(|e| e.to_string())?;
    let surface = off::read(&shell, Path::new("shell.off")).map_err(|e| e.to_string())?;
    let mut write = |reader: Reader, f: &dyn Fn(&mut Vec<u8>) -> std::io::Result<()>| {
        let mut out = Vec::new();
        if f(&mut out).is_ok() {
            seeds.entry(reader).or_default().push(out);
        }
    };
    write(Reader::Vtu, &|w| vtu::write(w, &mesh, &fields, vtu::Encoding::Inline));
    write(Reader::Vtu, &|w| vtu::write(w, &mesh, &fields, vtu::Encoding::Appended));
    write(Reader::Vtk, &|w| vtk::write(w, &mesh, &fields));
    write(Reader::Inp, &|w| inp::write(w, &mesh));
    write(Reader::Stl, &|w| stl::write_ascii(w, &surface));
    write(Reader::Stl, &|w| stl::write_binary(w, &surface));
    write(Reader::Obj, &|w| obj::write(w, &surface));
    write(Reader::Off, &|w| off::write(w, &surface));
    for r in Reader::ALL {
        if seeds.get(&r).is_none_or(|s| s.is_empty()) {
            return Err(format!("no seed input for the {} reader", r.name()));
        }
    }
    Ok(seeds)
}

/// The panic message and location of the panic being caught on the worker thread.
type PanicSlot = Arc<Mutex<Option<String>>>;

enum Outcome {
    Parsed(bool),
    Panicked(String),
}

/// The worker thread: parses each input under `catch_unwind`, with the allocator capped.
struct Worker {
    send: mpsc::Sender<(Reader, Vec<u8>)>,
    recv: mpsc::Receiver<Outcome>,
}

const WORKER_NAME: &str = "xtask-fuzz-worker";

impl Worker {
    fn start(cap_memory: bool, slot: PanicSlot) -> Worker {
        let (send, jobs) = mpsc::channel::<(Reader, Vec<u8>)>();
        let (done, recv) = mpsc::channel();
        std::thread::Builder::new()
            .name(WORKER_NAME.into())
            .spawn(move || {
                for (reader, input) in jobs {
                    if cap_memory {
                        let limit = crate::ALLOC
                            .allocated()
                            .saturating_add(input.len().saturating_mul(64))
                            .saturating_add(256 << 20);
                        let _ = crate::ALLOC.set_limit(limit);
                    }
                    let r = catch_unwind(AssertUnwindSafe(|| reader.parse(&input)));
                    if cap_memory {
                        let _ = crate::ALLOC.set_limit(usize::MAX);
                    }
                    let outcome = match r {
                        Ok(ok) => Outcome::Parsed(ok),
                        Err(payload) => Outcome::Panicked(
                            slot.lock()
                                .ok()
                                .and_then(|mut s| s.take())
                                .unwrap_or_else(|| payload_text(&payload)),
                        ),
                    };
                    if done.send(outcome).is_err() {
                        break;
                    }
                }
            })
            .expect("spawning a thread");
        Worker { send, recv }
    }
}

fn payload_text(payload: &Box<dyn Any + Send>) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic with a non-text payload".into())
}

/// Installs a panic hook that records panics of the worker thread (message and location)
/// instead of printing them, and leaves others to the previous hook.
fn install_hook(slot: PanicSlot) {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if std::thread::current().name() == Some(WORKER_NAME) {
            let at = info.location().map(|l| format!(" at {}:{}", l.file(), l.line()));
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_default();
            if let Ok(mut s) = slot.lock() {
                *s = Some(format!("panic '{msg}'{}", at.unwrap_or_default()));
            }
        } else {
            previous(info);
        }
    }));
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
        .args(["fuzz", "--replay"])
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

/// `cargo xtask fuzz --seconds N [--seed S]`.
pub fn main(args: &[String]) -> Result<(), String> {
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
                let limit = crate::ALLOC.allocated() + bytes.len() * 64 + (256 << 20);
                let _ = crate::ALLOC.set_limit(limit);
                let accepted = reader.parse(&bytes);
                let _ = crate::ALLOC.set_limit(usize::MAX);
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

    /// The cap the fuzzer sets makes an oversized allocation fail (here a fallible one, which
    /// reports instead of aborting).
    #[test]
    fn the_capped_allocator_refuses_beyond_its_limit() {
        let limit = crate::ALLOC.allocated() + (1 << 30);
        crate::ALLOC.set_limit(limit).unwrap();
        let r = Vec::<u8>::new().try_reserve_exact(2 << 30);
        crate::ALLOC.set_limit(usize::MAX).unwrap();
        assert!(r.is_err(), "a 2 GiB allocation passed a 1 GiB cap");
    }

    #[test]
    fn mutations_are_deterministic_and_change_the_input() {
        let seed = b"*NODE\n1, 0.0, 1.5, 2\n2, 3, 4, 5\n".to_vec();
        let run = |s| {
            let mut rng = Rng::new(s);
            (0..200)
                .map(|_| {
                    let mut d = seed.clone();
                    mutate_once(&mut rng, &mut d, b"other file\n");
                    d
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(run(3), run(3));
        assert!(run(3).iter().filter(|d| **d != seed).count() > 150);
        assert_eq!(number_spans(b"a -12.5e3 7"), vec![(2, 9), (10, 11)]);
    }
}
