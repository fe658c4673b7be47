//! The commands of `cargo xtask` and their arguments, parsed into the options the libraries
//! take (after rust-analyzer's `flags.rs`). [`COMMANDS`] is the one list of commands: the
//! help is printed from it, and [`parse`] accepts no other name.

use std::path::PathBuf;
use std::str::FromStr;

use bs_study::bench::e2e;
use bs_study::stability::trace;
use bs_study::{chart, fit, reference, stability, validate};

/// How a command must be built before it runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Build {
    /// As it is (checks and file writers).
    Any,
    /// Optimised: timings and studies of debug code mean nothing.
    Release,
}

/// One command: its name (one or two words), its arguments, what it does.
#[derive(Debug)]
pub struct Command {
    pub name: &'static str,
    pub usage: &'static str,
    pub help: &'static str,
    pub build: Build,
}

const fn cmd(name: &'static str, usage: &'static str, help: &'static str, build: Build) -> Command {
    Command { name, usage, help, build }
}

/// Every command of `cargo xtask`.
pub const COMMANDS: &[Command] = &[
    cmd(
        "deps",
        "",
        "check the workspace crate graph against the layering rules, every crate's modules \
         (all folders) for cycles, bs-dr's folders for their layer order, and every \
         dependency for a use",
        Build::Any,
    ),
    cmd(
        "bench solver",
        "",
        "kernel ns/element-step (1 vs 2 threads), the preconditioners' cycles against the \
         memory bandwidth, DR vs Newton",
        Build::Release,
    ),
    cmd(
        "bench contact",
        "",
        "contact handlers on the paper's benchmark (writes docs/contact-bench.md)",
        Build::Release,
    ),
    cmd(
        "bench e2e",
        "[--case NAME] [--repeat N]",
        "every contact fixture solved by DR (baseline) and Newton-Krylov (default): \
         preparation, solve, iterations, accuracy against CalculiX, peak memory, speed-up; \
         then the 852k-tet MNI152 mesh and the loads other than the push",
        Build::Release,
    ),
    cmd(
        "bench mesh",
        "",
        "meshing a labelmap at 4 mm (MNI152 mask and an MNI-sized ellipsoid), 1 and 2 threads",
        Build::Release,
    ),
    cmd(
        "bench warp",
        "",
        "warp and field of the MNI152 T1 template with the demo result, against reading the \
         image and a naive per-voxel TetLocator loop",
        Build::Release,
    ),
    cmd(
        "bench update",
        "[--scene SCENE.toml]",
        "the MNI152 craniotomy measured at 1..8 mm: eight updates of a live session, each \
         warm from the last, against cold solves of the same loads; the warped T1 after each",
        Build::Release,
    ),
    cmd(
        "bench fit",
        "",
        "fitting fixtures/fit's scan against imposing what it measures, cold and in a \
         session; the gravity estimate; 32 uncertainty samples",
        Build::Release,
    ),
    cmd(
        "bench serve",
        "",
        "`brainshift serve` over OpenIGTLink on loopback: a scan of fixtures/fit and eight \
         displacement sets of the MNI152 craniotomy, last byte sent -> warped image received",
        Build::Release,
    ),
    cmd(
        "ghost",
        "",
        "the warped MNI152 T1 where the demo's brain moved away and the exported field at the \
         50 most displaced nodes, for the identity and the harmonic extension outside the brain",
        Build::Any,
    ),
    cmd(
        "fit",
        "fixture | study [--quick] | gravity [--quick] | gravity-fixture | uncertainty \
         [--quick] | try SIGMA COVERAGE OUTLIERS MISALIGNMENT [FREE] | landmarks [N [SIGMA \
         [SEED]]]",
        "the measurement-fit fixtures, the fit study (docs/fit.md), the gravity study, the \
         uncertainty calibration (docs/uncertainty.md); try and landmarks write one case \
         into target/fit-try",
        Build::Release,
    ),
    cmd(
        "validate",
        "[--quick | --calculix CASE]",
        "every reference case (closed forms, DR vs Newton, contact vs brute force, DR + \
         contact vs CalculiX); writes docs/validation.md",
        Build::Release,
    ),
    cmd(
        "chart",
        "[--case ellipsoid|mni152] [--replot]",
        "speed vs accuracy: mesh density, element, DR tolerance, contact handler, DR vs \
         Newton, CalculiX; writes docs/charts/ and docs/speed-accuracy.md",
        Build::Release,
    ),
    cmd(
        "stability",
        "[--quick] | trace SCENE [--load MM] [--ramp STEPS] [--every K] [--at MM] [--out CSV]",
        "the stability map: time step, Poisson ratio, hourglass control, load until \
         inversion, contact lists at sharp corners (writes docs/charts/); trace: one DR run \
         step by step",
        Build::Release,
    ),
    cmd(
        "fuzz",
        "--seconds N [--seed S]",
        "the bs-fuzz program: mutate the fixtures for every reader (.inp .msh .vtk .vtu .stl \
         .obj .off, scene.toml); panics, hangs (> 5 s) and allocations beyond 64 x input + \
         256 MiB are findings, saved as fixtures/fuzz/<reader>-<n>.<ext>; exits non-zero on \
         any finding (profile `fuzzing`: optimised with overflow checks)",
        Build::Any,
    ),
    cmd(
        "reference",
        "[--case NAME] [--deck-only] [--timeout S] [--memory-gib G] [--threads N] [--slope K] \
         [--collect]",
        "CalculiX reference solutions of the contact fixtures, stored in \
         fixtures/<case>/reference/ (needs ccx)",
        Build::Any,
    ),
    cmd("help", "", "print this help", Build::Any),
];

/// A command with its arguments parsed.
#[derive(Debug, Clone)]
pub enum Task {
    Deps,
    Bench(Bench),
    Ghost,
    Fit(fit::Options),
    Validate(validate::Options),
    Chart(chart::Options),
    Stability(stability::Options),
    /// The arguments of the bs-fuzz program, passed on.
    Fuzz(Vec<String>),
    Reference(reference::Options),
    Help,
}

/// A benchmark with its arguments parsed.
#[derive(Debug, Clone)]
pub enum Bench {
    Solver,
    Contact,
    E2e(e2e::Options),
    /// One case of `bench e2e` in a child process ([`e2e::CHILD`]).
    E2eChild {
        case: String,
        solver: String,
        out: PathBuf,
    },
    Mesh,
    Warp,
    Update(Option<PathBuf>),
    Fit,
    Serve,
}

/// The command `args` names and how it must be built (`None`: not a command).
pub fn command(args: &[String]) -> Option<&'static Command> {
    let one = args.first()?;
    let two = args.get(1).map(|b| format!("{one} {b}"));
    COMMANDS.iter().find(|c| c.name == one || Some(c.name) == two.as_deref())
}

/// The help text, from [`COMMANDS`].
pub fn help() -> String {
    let mut s = String::from("cargo xtask <command>\n\nCommands:\n");
    for c in COMMANDS {
        let lines = [wrap(c.usage, 74), wrap(c.help, 74)].concat();
        for (i, line) in lines.iter().enumerate() {
            let name = if i == 0 { c.name } else { "" };
            s.push_str(&format!("  {name:<15} {line}\n"));
        }
    }
    s.push('\n');
    s.extend(
        wrap(
            "Benchmarks, studies and validation always run optimised: from a debug build they \
         re-run themselves with `cargo run --release`.",
            92,
        )
        .into_iter()
        .map(|l| l + "\n"),
    );
    s
}

/// The words of `text` in lines of at most `width` characters.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        if !line.is_empty() && line.len() + 1 + word.len() > width {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

/// The arguments after a command's name, read in order; errors name the command and its usage.
struct Args<'a> {
    rest: std::slice::Iter<'a, String>,
    command: &'static Command,
}

impl<'a> Args<'a> {
    fn next(&mut self) -> Option<&'a str> {
        self.rest.next().map(String::as_str)
    }

    fn error(&self, what: impl std::fmt::Display) -> String {
        let usage = format!("cargo xtask {} {}", self.command.name, self.command.usage);
        format!("{what}; usage: {}", usage.trim_end())
    }

    /// The value after `flag`.
    fn value(&mut self, flag: &str) -> Result<&'a str, String> {
        self.next().ok_or_else(|| self.error(format!("{flag} needs a value")))
    }

    /// The value after `flag`, parsed.
    fn number<T: FromStr>(&mut self, flag: &str) -> Result<T, String> {
        let v = self.value(flag)?;
        v.parse().map_err(|_| self.error(format!("{flag} {v}: not a number")))
    }

    /// `v` parsed as the positional argument `what`.
    fn positional<T: FromStr>(&self, what: &str, v: &str) -> Result<T, String> {
        v.parse().map_err(|_| self.error(format!("{what} {v}: not a number")))
    }

    fn unknown(&self, a: &str) -> String {
        self.error(format!("unknown argument '{a}'"))
    }

    /// Whether `--quick` comes next (the rest must then be empty: [`parse`] checks).
    fn quick(&mut self) -> Result<bool, String> {
        match self.next() {
            None => Ok(false),
            Some("--quick") => Ok(true),
            Some(a) => Err(self.unknown(a)),
        }
    }

    /// Nothing is left.
    fn end(&mut self) -> Result<(), String> {
        match self.next() {
            None => Ok(()),
            Some(a) => Err(self.unknown(a)),
        }
    }
}

/// Parses `cargo xtask` arguments (`args` without the program's name).
pub fn parse(args: &[String]) -> Result<Task, String> {
    if args.is_empty() || matches!(args[0].as_str(), "--help" | "-h") {
        return Ok(Task::Help);
    }
    if args[..args.len().min(3)] == e2e::CHILD {
        return match &args[3..] {
            [case, solver, out] => Ok(Task::Bench(Bench::E2eChild {
                case: case.clone(),
                solver: solver.clone(),
                out: out.into(),
            })),
            _ => Err("usage: cargo xtask bench e2e --one CASE SOLVER OUT".into()),
        };
    }
    let Some(command) = command(args) else {
        return Err(match args.first().map(String::as_str) {
            Some("bench") => "bench what? `cargo xtask help` lists the benchmarks".into(),
            _ => format!("unknown command '{}'; `cargo xtask help` lists the commands", args[0]),
        });
    };
    let skip = command.name.split(' ').count();
    let mut a = Args { rest: args[skip..].iter(), command };
    let task = match command.name {
        "deps" => Task::Deps,
        "ghost" => Task::Ghost,
        "help" => Task::Help,
        "fuzz" => return Ok(Task::Fuzz(args[1..].to_vec())),
        "fit" => Task::Fit(fit_options(&mut a)?),
        "validate" => Task::Validate(match a.next() {
            None => validate::Options::Table(validate::Scope::Full),
            Some("--quick") => validate::Options::Table(validate::Scope::Quick),
            Some("--calculix") => validate::Options::Calculix(a.value("--calculix")?.into()),
            Some(x) => return Err(a.unknown(x)),
        }),
        "chart" => Task::Chart(chart_options(&mut a)?),
        "stability" => Task::Stability(stability_options(&mut a)?),
        "reference" => Task::Reference(reference_options(&mut a)?),
        bench => Task::Bench(bench_options(bench, &mut a)?),
    };
    a.end()?;
    Ok(task)
}

fn bench_options(name: &str, a: &mut Args<'_>) -> Result<Bench, String> {
    Ok(match name {
        "bench solver" => Bench::Solver,
        "bench contact" => Bench::Contact,
        "bench mesh" => Bench::Mesh,
        "bench warp" => Bench::Warp,
        "bench fit" => Bench::Fit,
        "bench serve" => Bench::Serve,
        "bench update" => match a.next() {
            None => Bench::Update(None),
            Some("--scene") => Bench::Update(Some(a.value("--scene")?.into())),
            Some(x) => return Err(a.unknown(x)),
        },
        "bench e2e" => {
            let mut o = e2e::Options { case: None, repeat: 1 };
            while let Some(flag) = a.next() {
                match flag {
                    "--case" => o.case = Some(a.value(flag)?.into()),
                    "--repeat" => o.repeat = a.number(flag)?,
                    x => return Err(a.unknown(x)),
                }
            }
            Bench::E2e(o)
        }
        other => unreachable!("'{other}' is in COMMANDS but not parsed"),
    })
}

fn fit_options(a: &mut Args<'_>) -> Result<fit::Options, String> {
    Ok(match a.next() {
        Some("fixture") => fit::Options::Fixture,
        Some("gravity-fixture") => fit::Options::GravityFixture,
        Some("study") => fit::Options::Study { quick: a.quick()? },
        Some("gravity") => fit::Options::Gravity { quick: a.quick()? },
        Some("uncertainty") => fit::Options::Uncertainty { quick: a.quick()? },
        Some("try") => {
            let mut v = [1.0, 1.0, 0.0, 0.0, 0.0];
            let names = ["SIGMA", "COVERAGE", "OUTLIERS", "MISALIGNMENT", "FREE"];
            for (slot, name) in v.iter_mut().zip(names) {
                let Some(x) = a.next() else { break };
                *slot = a.positional(name, x)?;
            }
            let [sigma, coverage, outliers, misalignment, free] = v;
            fit::Options::Try { sigma, coverage, outliers, misalignment, free: free != 0.0 }
        }
        Some("landmarks") => {
            let n = a.next().map(|x| a.positional("N", x)).transpose()?.unwrap_or(15);
            let sigma = a.next().map(|x| a.positional("SIGMA", x)).transpose()?.unwrap_or(1.0);
            let seed = a.next().map(|x| a.positional("SEED", x)).transpose()?.unwrap_or(1000);
            fit::Options::Landmarks { n, sigma, seed }
        }
        Some(x) => return Err(a.unknown(x)),
        None => return Err(a.error("fit what?")),
    })
}

fn chart_options(a: &mut Args<'_>) -> Result<chart::Options, String> {
    let mut o = chart::Options::default();
    while let Some(flag) = a.next() {
        match flag {
            "--case" => o.case = Some(a.value(flag)?.into()),
            "--replot" => o.replot = true,
            x => return Err(a.unknown(x)),
        }
    }
    Ok(o)
}

fn stability_options(a: &mut Args<'_>) -> Result<stability::Options, String> {
    Ok(match a.next() {
        None => stability::Options::Map(stability::Scope::Full),
        Some("--quick") => stability::Options::Map(stability::Scope::Quick),
        Some("trace") => {
            let scene = a.next().ok_or_else(|| a.error("trace needs a scene"))?.into();
            let mut t =
                trace::Options { scene, load: None, ramp: None, every: 5, at: None, out: None };
            while let Some(flag) = a.next() {
                match flag {
                    "--load" => t.load = Some(a.number(flag)?),
                    "--ramp" => t.ramp = Some(a.number(flag)?),
                    "--every" => t.every = a.number::<usize>(flag)?.max(1),
                    "--at" => t.at = Some(a.number(flag)?),
                    "--out" => t.out = Some(a.value(flag)?.into()),
                    x => return Err(a.unknown(x)),
                }
            }
            stability::Options::Trace(t)
        }
        Some(x) => return Err(a.unknown(x)),
    })
}

fn reference_options(a: &mut Args<'_>) -> Result<reference::Options, String> {
    let mut o = reference::Options::default();
    while let Some(flag) = a.next() {
        match flag {
            "--case" => o.only = Some(a.value(flag)?.into()),
            "--deck-only" => o.deck_only = true,
            "--timeout" => o.timeout = a.number(flag)?,
            "--memory-gib" => o.memory_gib = a.number(flag)?,
            "--threads" => o.threads = a.number(flag)?,
            "--slope" => o.slope = Some(a.number(flag)?),
            "--collect" => o.collect_only = true,
            x => return Err(a.unknown(x)),
        }
    }
    Ok(o)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(s: &str) -> Result<Task, String> {
        parse(&s.split_whitespace().map(String::from).collect::<Vec<_>>())
    }

    /// Every command of the list parses with no arguments, except those that need one.
    #[test]
    fn every_listed_command_parses() {
        for c in COMMANDS {
            let needs = matches!(c.name, "fit");
            assert_eq!(parsed(c.name).is_ok(), !needs, "{}: {:?}", c.name, parsed(c.name));
        }
        assert!(help().lines().count() > COMMANDS.len() * 2, "{}", help());
        assert!(help().lines().all(|l| l.len() <= 92), "{}", help());
    }

    #[test]
    fn trace_options_are_read_and_bad_ones_refused_by_name() {
        let t = match parsed(
            "stability trace s.toml --load 40 --ramp 800 --every 0 --at 35 --out t.csv",
        ) {
            Ok(Task::Stability(stability::Options::Trace(t))) => t,
            other => panic!("{other:?}"),
        };
        assert_eq!(t.scene, PathBuf::from("s.toml"));
        assert_eq!((t.load, t.ramp, t.every, t.at), (Some(40.0), Some(800), 1, Some(35.0)));
        assert_eq!(t.out, Some(PathBuf::from("t.csv")));
        let err = |s| parsed(s).unwrap_err();
        assert!(err("stability trace s.toml --speed 2").contains("'--speed'"));
        assert!(err("stability trace s.toml --load forty").contains("forty: not a number"));
        assert!(err("stability trace s.toml --at").contains("--at needs a value"));
        assert!(err("stability trace").contains("usage: cargo xtask stability"));
    }

    #[test]
    fn arguments_reach_their_options() {
        match parsed("bench e2e --case mni152 --repeat 3") {
            Ok(Task::Bench(Bench::E2e(o))) => {
                assert_eq!((o.case.as_deref(), o.repeat), (Some("mni152"), 3))
            }
            other => panic!("{other:?}"),
        }
        match parsed("bench e2e --one sphere-shell dr /tmp/x.csv") {
            Ok(Task::Bench(Bench::E2eChild { case, solver, out })) => {
                assert_eq!((case.as_str(), solver.as_str()), ("sphere-shell", "dr"));
                assert_eq!(out, PathBuf::from("/tmp/x.csv"));
            }
            other => panic!("{other:?}"),
        }
        match parsed("fit landmarks 20 0.5") {
            Ok(Task::Fit(fit::Options::Landmarks { n, sigma, seed })) => {
                assert_eq!((n, sigma, seed), (20, 0.5, 1000))
            }
            other => panic!("{other:?}"),
        }
        match parsed("reference --case mni152 --slope 10 --collect") {
            Ok(Task::Reference(o)) => {
                assert_eq!(
                    (o.only.as_deref(), o.slope, o.collect_only),
                    (Some("mni152"), Some(10.0), true)
                )
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            parsed("validate --calculix regions-held"),
            Ok(Task::Validate(validate::Options::Calculix(c))) if c == "regions-held"
        ));
        assert!(matches!(parsed("fuzz --seconds 5"), Ok(Task::Fuzz(a)) if a == ["--seconds", "5"]));
    }

    #[test]
    fn bad_arguments_are_refused_with_the_usage() {
        let err = |s| parsed(s).unwrap_err();
        assert!(err("bench warp --fast").contains("unknown argument '--fast'"));
        assert!(err("bench warp --fast").contains("usage: cargo xtask bench warp"));
        assert!(err("bench e2e --repeat x").contains("--repeat x: not a number"));
        assert!(err("bench").contains("bench what?"));
        assert!(err("bench nothing").contains("bench what?"));
        assert!(err("validate --quick extra").contains("'extra'"));
        assert!(err("fit").contains("fit what?"));
        assert!(err("fit try 1 x").contains("COVERAGE x"));
        assert!(err("frobnicate").contains("unknown command 'frobnicate'"));
    }
}
