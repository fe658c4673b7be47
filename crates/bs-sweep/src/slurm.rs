//! A Slurm array job for a sweep: one array task per row, each calling
//! `brainshift sweep run DIR --index $SLURM_ARRAY_TASK_ID --threads $SLURM_CPUS_PER_TASK`,
//! with its memory request from [`bs_scene::memory::estimate`] (the figure `brainshift check`
//! prints) of the largest distinct scene in the sweep.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use super::{Manifest, SweepError, create_dir, write_text};
use bs_scene::{Prepared, Scene};

/// Options of the emitted script.
#[derive(Debug, Clone)]
pub struct SlurmOptions {
    /// At most this many rows run at once (`%M` of `--array`); none: no limit.
    pub max_parallel: Option<usize>,
    /// Wall-time limit per row, `HH:MM:SS` or `D-HH:MM:SS`.
    pub time: String,
    /// Cores per row (`--cpus-per-task`, passed on as `--threads`).
    pub cpus_per_task: usize,
    /// The `brainshift` program the tasks call (an absolute path on the cluster).
    pub program: String,
}

/// The written script and what it asks for.
#[derive(Debug, Clone, PartialEq)]
pub struct SlurmScript {
    /// `DIR/sweep.slurm`.
    pub path: PathBuf,
    /// Its text.
    pub text: String,
    /// Number of array tasks (rows).
    pub tasks: usize,
    /// Memory per task (MB), the estimate with 50 % headroom.
    pub mem_mb: u64,
}

/// Checks a Slurm time limit: `MM`, `MM:SS`, `HH:MM:SS`, `D-HH`, `D-HH:MM` or `D-HH:MM:SS`.
fn valid_time(t: &str) -> bool {
    let (days, rest) = match t.split_once('-') {
        Some((d, r)) => (Some(d), r),
        None => (None, t),
    };
    let digits = |s: &str| !s.is_empty() && s.len() <= 4 && s.bytes().all(|b| b.is_ascii_digit());
    let parts: Vec<&str> = rest.split(':').collect();
    days.is_none_or(digits) && (1..=3).contains(&parts.len()) && parts.iter().all(|p| digits(p))
}

/// Quotes a word for a POSIX shell.
fn shell_quote(s: &str) -> String {
    if !s.is_empty() && s.bytes().all(|b| b.is_ascii_alphanumeric() || b"/._-+=:@".contains(&b)) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// Writes `DIR/sweep.slurm` (and the `DIR/logs/` folder its tasks write to).
pub fn emit_slurm(dir: &Path, opts: &SlurmOptions) -> Result<SlurmScript, SweepError> {
    let bad = |message: String| SweepError::Dir { dir: dir.to_path_buf(), message };
    if !valid_time(&opts.time) {
        return Err(bad(format!(
            "--time {}: give the wall-time limit per row as HH:MM:SS (or D-HH:MM:SS)",
            opts.time
        )));
    }
    if opts.max_parallel == Some(0) {
        return Err(bad("--max-parallel 0: give at least 1 (or leave it out for no limit)".into()));
    }
    if opts.cpus_per_task == 0 {
        return Err(bad("--cpus-per-task 0: give at least 1".into()));
    }
    let manifest = Manifest::read(dir)?;
    if manifest.rows.is_empty() {
        return Err(bad("the sweep has no rows".into()));
    }
    let abs = std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf());
    // The memory estimate depends on the mesh, the skull and the solver: prepare one scene
    // per distinct combination and ask for the largest.
    let mut seen = BTreeSet::new();
    let mut estimate: f64 = 0.0;
    for row in &manifest.rows {
        let path = dir.join(&row.scene);
        let scene =
            Scene::load(&path).map_err(|source| SweepError::Row { index: row.index, source })?;
        let key = (
            scene.mesh.file.clone(),
            scene.contact.as_ref().map(|c| c.skull.clone()),
            scene.solver.kind.name(),
        );
        if seen.insert(key) {
            let p = Prepared::from_scene(&path, scene)
                .map_err(|source| SweepError::Row { index: row.index, source })?;
            estimate = estimate.max(bs_scene::memory::estimate(&p));
        }
    }
    let mem_mb = ((estimate * 1.5 / 1e6).ceil() as u64).max(256);
    let tasks = manifest.rows.len();
    let array = match opts.max_parallel {
        Some(m) => format!("0-{}%{m}", tasks - 1),
        None => format!("0-{}", tasks - 1),
    };
    let logs = abs.join("logs");
    create_dir(&logs)?;
    let d = shell_quote(&abs.to_string_lossy());
    let text = format!(
        "#!/bin/bash\n\
         # brainshift sweep of {sweep}: {tasks} rows, one array task each.\n\
         # Memory: brainshift's estimate for the largest scene ({est:.0} MB) plus 50 %.\n\
         # Submit with: sbatch {script}\n\
         # Then: brainshift sweep collect {d}\n\
         #SBATCH --job-name=brainshift-sweep\n\
         #SBATCH --array={array}\n\
         #SBATCH --cpus-per-task={cpus}\n\
         #SBATCH --mem={mem_mb}M\n\
         #SBATCH --time={time}\n\
         #SBATCH --output={logs}/%a.out\n\
         set -euo pipefail\n\
         exec {program} sweep run {d} --index \"$SLURM_ARRAY_TASK_ID\" --threads \"${{SLURM_CPUS_PER_TASK:-{cpus}}}\"\n",
        sweep = manifest.sweep.display(),
        est = estimate / 1e6,
        script = shell_quote(&abs.join("sweep.slurm").to_string_lossy()),
        cpus = opts.cpus_per_task,
        time = opts.time,
        logs = logs.display(),
        program = shell_quote(&opts.program),
    );
    let path = dir.join("sweep.slurm");
    write_text(&path, &text)?;
    Ok(SlurmScript { path, text, tasks, mem_mb })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_script_asks_for_every_row_with_the_estimated_memory() {
        let dir = crate::planned_cube_sweep(
            "slurm",
            "[[axis]]\nkey = \"region.material.youngs_modulus\"\n\
             range = [1000.0, 5000.0]\nsamples = 5\n",
        );
        let opts = SlurmOptions {
            max_parallel: Some(2),
            time: "00:10:00".into(),
            cpus_per_task: 2,
            program: "/opt/brainshift/bin/brainshift".into(),
        };
        let script = emit_slurm(&dir, &opts).unwrap();
        let text = std::fs::read_to_string(dir.join("sweep.slurm")).unwrap();
        assert_eq!(text, script.text);
        assert_eq!(script.tasks, 5);
        let p = Prepared::load(&dir.join("scenes/0.toml")).unwrap();
        let mem = ((bs_scene::memory::estimate(&p) * 1.5 / 1e6).ceil() as u64).max(256);
        assert_eq!(script.mem_mb, mem);
        for line in [
            "#SBATCH --array=0-4%2\n".to_string(),
            "#SBATCH --cpus-per-task=2\n".to_string(),
            format!("#SBATCH --mem={mem}M\n"),
            "#SBATCH --time=00:10:00\n".to_string(),
            "exec /opt/brainshift/bin/brainshift sweep run ".to_string(),
            " --index \"$SLURM_ARRAY_TASK_ID\" --threads \"${SLURM_CPUS_PER_TASK:-2}\"\n".into(),
        ] {
            assert!(text.contains(&line), "{line}\n{text}");
        }
        assert!(text.starts_with("#!/bin/bash\n"));
        assert!(dir.join("logs").is_dir());
        let no_limit = emit_slurm(&dir, &SlurmOptions { max_parallel: None, ..opts.clone() });
        assert!(no_limit.unwrap().text.contains("#SBATCH --array=0-4\n"));
        for (bad, expect) in [
            (SlurmOptions { time: "10 minutes".into(), ..opts.clone() }, "--time 10 minutes"),
            (SlurmOptions { max_parallel: Some(0), ..opts.clone() }, "--max-parallel 0"),
        ] {
            let e = emit_slurm(&dir, &bad).unwrap_err().to_string();
            assert!(e.contains(expect), "{e}");
        }
        let e = emit_slurm(&dir.parent().unwrap().join("nowhere"), &opts).unwrap_err().to_string();
        assert!(e.contains("cannot read manifest.json"), "{e}");
    }

    #[test]
    fn time_limits_and_quoting() {
        for t in ["10", "10:00", "01:00:00", "1-00", "2-12:00:00"] {
            assert!(valid_time(t), "{t}");
        }
        for t in ["", "1h", "01:00:00:00", "a-01:00", "1-"] {
            assert!(!valid_time(t), "{t}");
        }
        assert_eq!(shell_quote("/a/b c"), "'/a/b c'");
        assert_eq!(shell_quote("it's"), "'it'\\''s'");
        assert_eq!(shell_quote("/usr/bin/brainshift"), "/usr/bin/brainshift");
    }
}
