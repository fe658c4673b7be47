//! Running one row of a sweep into `DIR/runs/I/`, idempotently and atomically: a row whose
//! complete report.json is there is skipped; otherwise the row is run into a temporary
//! folder (`DIR/runs/.I.PID.tmp`) renamed into place at the end, so an interrupted run
//! leaves no half-written row (its stale temporary folder is removed by the next attempt).
//! A failed row leaves `DIR/runs/I/error.json` with the error's kind and message.

use std::path::{Path, PathBuf};
use std::time::Instant;

use bs_dr::Progress;

use super::{Manifest, SweepError, create_dir, write_text};
use bs_scene::output::{RunContext, report, write_outputs};
use bs_scene::{Prepared, Run, SceneError};

/// What [`run_row`] did.
#[derive(Debug, Clone, PartialEq)]
pub enum RowOutcome {
    /// The row ran and its files are in the returned folder.
    Ran(PathBuf),
    /// The row had already run: its complete report was there and nothing was done.
    Skipped(PathBuf),
}

/// The folder of row `index`.
pub fn row_dir(dir: &Path, index: usize) -> PathBuf {
    dir.join("runs").join(index.to_string())
}

/// True when `runs/I/report.json` is a complete report of a converged run.
pub(crate) fn has_report(row: &Path) -> bool {
    bs_scene::output::RunReport::read(&row.join("report.json")).is_ok_and(|r| r.converged)
}

/// Runs row `index` of the sweep in `dir` (see the module documentation). `threads` is
/// what the report records (the caller sets up the thread pool); `observer` sees every
/// solver step. A failed row returns its error after writing error.json.
pub fn run_row(
    dir: &Path,
    index: usize,
    threads: usize,
    observer: &mut dyn FnMut(&Progress),
) -> Result<RowOutcome, SweepError> {
    let started = Instant::now();
    let manifest = Manifest::read(dir)?;
    let row = manifest.row(dir, index)?;
    let runs = dir.join("runs");
    let out = row_dir(dir, index);
    if has_report(&out) {
        return Ok(RowOutcome::Skipped(out));
    }
    create_dir(&runs)?;
    remove_stale(&runs, index)?;
    let tmp = runs.join(format!(".{index}.{}.tmp", std::process::id()));
    create_dir(&tmp)?;
    let result = solve_into(&dir.join(&row.scene), &tmp, threads, started, observer);
    if let Err(e) = &result {
        let json = serde_json::json!({
            "index": index,
            "kind": e.kind(),
            "message": e.to_string(),
        });
        let text = serde_json::to_string_pretty(&json).expect("json serialises");
        write_text(&tmp.join("error.json"), &format!("{text}\n"))?;
    }
    // Replace whatever an earlier attempt left (a failed row's error.json).
    if out.exists() {
        std::fs::remove_dir_all(&out).map_err(|e| SweepError::Write {
            path: out.clone(),
            message: format!("cannot replace the earlier attempt: {e}"),
        })?;
    }
    std::fs::rename(&tmp, &out).map_err(|e| SweepError::Write {
        path: out.clone(),
        message: format!("cannot move {} into place: {e}", tmp.display()),
    })?;
    match result {
        Ok(()) => Ok(RowOutcome::Ran(out)),
        Err(source) => Err(SweepError::Row { index, source }),
    }
}

/// Removes temporary folders of row `index` left by interrupted attempts.
fn remove_stale(runs: &Path, index: usize) -> Result<(), SweepError> {
    let prefix = format!(".{index}.");
    let Ok(entries) = std::fs::read_dir(runs) else { return Ok(()) };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with(&prefix) && name.ends_with(".tmp") {
            std::fs::remove_dir_all(entry.path()).map_err(|e| SweepError::Write {
                path: entry.path(),
                message: format!("cannot remove an interrupted attempt's folder: {e}"),
            })?;
        }
    }
    Ok(())
}

/// What `brainshift run` does for one scene, into `out`: the same bs-scene calls, so the
/// files are those of the command.
fn solve_into(
    scene: &Path,
    out: &Path,
    threads: usize,
    started: Instant,
    observer: &mut dyn FnMut(&Progress),
) -> Result<(), SceneError> {
    let prepared = Prepared::load(scene)?;
    let mut run = Run::prepare(prepared)?;
    let solved = run.solve(observer)?;
    let ctx = RunContext { total_seconds: started.elapsed().as_secs_f64(), threads };
    let report = report(&run, &solved, ctx);
    write_outputs(out, &run.prepared, &solved, &report)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn planned(name: &str, values: &str) -> PathBuf {
        crate::planned_cube_sweep(
            &format!("run-{name}"),
            &format!("[[axis]]\nkey = \"boundary.3.displacement.z\"\nvalues = {values}\n"),
        )
    }

    #[test]
    fn a_second_run_of_a_row_is_skipped_and_a_stale_temp_folder_is_cleaned() {
        let dir = planned("idem", "[-0.05, -0.1]");
        // An interrupted earlier attempt: a temporary folder with a partial file.
        let stale = dir.join("runs/.0.999999.tmp");
        std::fs::create_dir_all(&stale).unwrap();
        std::fs::write(stale.join("result.vtu"), "partial").unwrap();
        let first = run_row(&dir, 0, 1, &mut |_| {}).unwrap();
        assert_eq!(first, RowOutcome::Ran(dir.join("runs/0")));
        assert!(!stale.exists(), "the stale folder is removed");
        for f in ["result.vtu", "displacements.csv", "report.json"] {
            assert!(dir.join("runs/0").join(f).exists(), "{f}");
        }
        let report = std::fs::read_to_string(dir.join("runs/0/report.json")).unwrap();
        let second = run_row(&dir, 0, 1, &mut |_| panic!("a skipped row does not solve")).unwrap();
        assert_eq!(second, RowOutcome::Skipped(dir.join("runs/0")));
        assert_eq!(std::fs::read_to_string(dir.join("runs/0/report.json")).unwrap(), report);
        // No temporary folder is left behind.
        let left: Vec<_> = std::fs::read_dir(dir.join("runs"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(left, ["0"]);
        // A row that does not exist is an error naming the range.
        let e = run_row(&dir, 2, 1, &mut |_| {}).unwrap_err().to_string();
        assert!(e.contains("there is no row 2: the sweep has 2 rows (0 to 1)"), "{e}");
    }

    #[test]
    fn a_failed_row_writes_error_json_and_a_rerun_replaces_it() {
        // Half the cube's size pushes the top face through the bottom: refused.
        let dir = planned("fail", "[-0.9]");
        let e = run_row(&dir, 0, 1, &mut |_| {}).unwrap_err();
        assert!(matches!(e, SweepError::Row { index: 0, .. }), "{e}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("runs/0/error.json")).unwrap())
                .unwrap();
        assert_eq!(json["index"], 0);
        assert!(json["message"].as_str().unwrap().contains("exceeds half the mesh size"), "{json}");
        assert!(!has_report(&dir.join("runs/0")));
    }
}
