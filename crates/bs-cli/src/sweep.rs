//! `brainshift sweep plan|run|collect|emit-slurm`: parameter sweeps as folders
//! ([`bs_sweep`]): plan the rows, run any row anywhere (a laptop loop, a Slurm
//! array, Dask workers), collect one table.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use bs_sweep::{self as sweep, RowOutcome, SlurmOptions, Status};

/// `sweep plan SWEEP.toml --out DIR`.
pub fn plan(sweep_file: &Path, out: &Path) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let m = sweep::plan(sweep_file, out)?;
    crate::emit(&format!(
        "planned {} rows ({}) of {} over {} into {}\nrun one with: brainshift sweep run {} \
         --index I\n",
        m.rows.len(),
        m.method,
        m.base.display(),
        m.keys.join(", "),
        out.display(),
        out.display()
    ));
    Ok(ExitCode::SUCCESS)
}

/// `sweep run DIR --index I [--threads N]`: exits 1 when the row fails (its error.json
/// written).
pub fn run(
    dir: &Path,
    index: usize,
    threads: Option<usize>,
    quiet: bool,
) -> Result<ExitCode, Box<dyn std::error::Error>> {
    crate::run::init_threads(threads)?;
    let threads = rayon::current_num_threads();
    match sweep::run_row(dir, index, threads, &mut |_| {})? {
        RowOutcome::Ran(out) if !quiet => {
            let report = bs_scene::output::RunReport::read(&out.join("report.json"))?;
            crate::emit(&format!(
                "row {index}: converged, max displacement {} {}, {:.3} s solve; wrote {}\n",
                report.max_displacement,
                report.units.map_or("", |u| u.symbol()),
                report.solve_seconds,
                out.display()
            ));
        }
        RowOutcome::Skipped(out) if !quiet => {
            crate::emit(&format!(
                "row {index}: already done ({} holds a complete report.json); skipped\n",
                out.display()
            ));
        }
        _ => {}
    }
    Ok(ExitCode::SUCCESS)
}

/// `sweep collect DIR [--points points.csv]`: writes DIR/summary.csv, prints the counts and
/// every failed row with its error.
pub fn collect(dir: &Path, points: Option<&Path>) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let points = match points {
        Some(p) => sweep::read_points(p)?,
        None => Vec::new(),
    };
    let s = sweep::collect(dir, &points)?;
    let mut text = format!(
        "{} rows: {} ok, {} failed, {} missing; wrote {}\n",
        s.rows.len(),
        s.count(Status::Ok),
        s.count(Status::Failed),
        s.count(Status::Missing),
        s.path.display()
    );
    for r in s.rows.iter().filter(|r| r.status == Status::Failed) {
        text.push_str(&format!(
            "  row {} failed: {}\n",
            r.index,
            r.error.as_deref().unwrap_or("(no message)")
        ));
    }
    crate::emit(&text);
    Ok(ExitCode::SUCCESS)
}

/// `sweep emit-slurm DIR`.
pub fn emit_slurm(
    dir: &Path,
    max_parallel: Option<usize>,
    time: &str,
    cpus_per_task: usize,
    program: Option<PathBuf>,
) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let program = match program {
        Some(p) => p,
        None => std::env::current_exe()
            .map_err(|e| format!("cannot tell where brainshift is ({e}); give --program PATH"))?,
    };
    let opts = SlurmOptions {
        max_parallel,
        time: time.to_string(),
        cpus_per_task,
        program: program.to_string_lossy().into_owned(),
    };
    let s = sweep::emit_slurm(dir, &opts)?;
    crate::emit(&format!(
        "wrote {} ({} array tasks, {} cores and {} MB each)\nsubmit with: sbatch {}\n",
        s.path.display(),
        s.tasks,
        cpus_per_task,
        s.mem_mb,
        s.path.display()
    ));
    Ok(ExitCode::SUCCESS)
}
