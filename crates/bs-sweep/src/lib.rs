//! Parameter sweeps as data: a sweep file names a base scene and the parameters to vary;
//! [`plan()`] expands it into one scene file per row and a manifest, [`run_row`] runs one row
//! into its own folder (idempotently, atomically), [`collect()`] gathers every row into one
//! table, and [`emit_slurm`] writes a Slurm array job that runs the rows on a cluster. Every
//! front end (the `brainshift sweep` commands, the Python bindings' Dask runner) drives
//! these functions, so a sweep folder is the same whatever ran it.
//!
//! ```toml
//! base = "scene.toml"            # relative to the sweep file
//! method = "grid"                # or "lhs" (Latin hypercube) with seed and samples
//! [[axis]]
//! key = "region.material.youngs_modulus"   # every [[region]] that has the key
//! values = [1500.0, 3000.0, 6000.0]
//! [[axis]]
//! key = "boundary.1.displacement.z"        # one entry (0-based) of an array of tables
//! range = [-12.0, -4.0]
//! samples = 3
//! ```
//!
//! A sweep folder holds `manifest.csv`, `manifest.json`, `scenes/I.toml` (paths made
//! absolute), and after runs `runs/I/` (the files `brainshift run` writes, or `error.json`)
//! and `summary.csv`.
//!
//! Files:
//! * `plan.rs`: `plan`, `plan_text`: a sweep file expanded (grid or seeded Latin hypercube)
//!   into the rows' scene files and the manifest;
//! * `run.rs`: `run_row`, `row_dir`, `RowOutcome`: one row run into a temporary folder
//!   renamed into place;
//! * `collect.rs`: `collect`, `Summary`, `read_points`: every row's report.json into
//!   `summary.csv`, with the displacement at named points;
//! * `slurm.rs`: `emit_slurm`, `SlurmOptions`: an array job sized by bs-scene's memory
//!   estimate.
//!
//! Architecture invariant: bs-sweep knows scenes only as TOML tables to vary and as runs to
//! start through bs-scene; it composes nothing and solves nothing itself.

mod collect;
mod plan;
mod run;
mod slurm;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use collect::{NamedPoint, Status, Summary, SummaryRow, collect, read_points};
pub use plan::{plan, plan_text};
pub use run::{RowOutcome, row_dir, run_row};
pub use slurm::{SlurmOptions, SlurmScript, emit_slurm};

use bs_scene::SceneError;

/// Why a sweep cannot be planned, run, collected or submitted.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// The sweep file cannot be read, or one of its keys is wrong.
    #[error("{}: {message}", file.display())]
    File {
        /// The sweep file.
        file: PathBuf,
        /// What is wrong with which key, and how to fix it.
        message: String,
    },
    /// The sweep folder is not usable (no manifest, a row that does not exist, a different
    /// sweep already planned there).
    #[error("{}: {message}", dir.display())]
    Dir {
        /// The sweep folder.
        dir: PathBuf,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// A row's scene cannot run (the scene's own error, naming its file and key).
    #[error("row {index}: {source}")]
    Row {
        /// The row.
        index: usize,
        /// Why the scene failed.
        source: SceneError,
    },
    /// A file or folder could not be written.
    #[error("{}: {message}", path.display())]
    Write {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's message.
        message: String,
    },
}

impl SweepError {
    /// A short stable name of the error kind (the scene's kind for a failed row).
    pub fn kind(&self) -> &'static str {
        match self {
            SweepError::File { .. } => "SweepFile",
            SweepError::Dir { .. } => "SweepDir",
            SweepError::Row { source, .. } => source.kind(),
            SweepError::Write { .. } => "Write",
        }
    }
}

/// One value of a swept parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum AxisValue {
    /// A number (moduli, displacements, tolerances, step counts).
    Number(f64),
    /// Text (a mesh file, a solver kind, a contact algorithm).
    Text(String),
}

impl AxisValue {
    /// The value as a CSV field (numbers in their shortest round-trip form).
    pub fn csv(&self) -> String {
        match self {
            AxisValue::Number(x) => format!("{x:?}"),
            AxisValue::Text(s) => csv_field(s),
        }
    }
}

/// One row of a planned sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// 0-based row number (the Slurm array index).
    pub index: usize,
    /// One value per axis, in the order of [`Manifest::keys`].
    pub parameters: Vec<AxisValue>,
    /// The row's scene file, relative to the sweep folder.
    pub scene: PathBuf,
}

/// `manifest.json`: what a sweep folder holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// The sweep file (absolute).
    pub sweep: PathBuf,
    /// The base scene (absolute).
    pub base: PathBuf,
    /// `"grid"` or `"lhs"`.
    pub method: String,
    /// Seed of a Latin hypercube.
    pub seed: Option<u64>,
    /// The swept keys, one per axis.
    pub keys: Vec<String>,
    /// The rows.
    pub rows: Vec<Row>,
}

impl Manifest {
    /// Reads `DIR/manifest.json`.
    pub fn read(dir: &Path) -> Result<Manifest, SweepError> {
        let path = dir.join("manifest.json");
        let bad = |message: String| SweepError::Dir { dir: dir.to_path_buf(), message };
        let text = std::fs::read_to_string(&path).map_err(|e| {
            bad(format!(
                "cannot read manifest.json ({e}); is this a sweep folder? Create one with \
                 `brainshift sweep plan SWEEP.toml --out {}`",
                dir.display()
            ))
        })?;
        serde_json::from_str(&text).map_err(|e| {
            bad(format!("manifest.json is not a sweep manifest ({e}); plan the sweep again"))
        })
    }

    /// The row `index`, or an error naming the valid range.
    pub fn row(&self, dir: &Path, index: usize) -> Result<&Row, SweepError> {
        self.rows.get(index).ok_or_else(|| SweepError::Dir {
            dir: dir.to_path_buf(),
            message: format!(
                "there is no row {index}: the sweep has {} rows (0 to {})",
                self.rows.len(),
                self.rows.len().saturating_sub(1)
            ),
        })
    }
}

/// Quotes a CSV field when it holds a comma, a quote or a line break.
pub(crate) fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Writes `text` to `path` atomically (temporary file renamed into place).
pub(crate) fn write_text(path: &Path, text: &str) -> Result<(), SweepError> {
    bs_atomic::write_atomic(path, |w| w.write_all(text.as_bytes()))
        .map_err(|e| SweepError::Write { path: path.to_path_buf(), message: e.to_string() })
}

/// Creates a folder (and its parents).
pub(crate) fn create_dir(path: &Path) -> Result<(), SweepError> {
    std::fs::create_dir_all(path).map_err(|e| SweepError::Write {
        path: path.to_path_buf(),
        message: format!("cannot create the folder: {e}"),
    })
}

/// A sweep over the cube fixture planned into a fresh temporary folder, for the sweep
/// modules' tests: `axes` is the sweep file's `[[axis]]` part. Returns the sweep folder.
#[cfg(test)]
pub(crate) fn planned_cube_sweep(name: &str, axes: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bs-sweep-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/cube/uniaxial-t4.toml");
    let s = d.join("sweep.toml");
    std::fs::write(&s, format!("base = {:?}\n{axes}", base.to_str().unwrap())).unwrap();
    let dir = d.join("sweep");
    plan(&s, &dir).unwrap();
    dir
}
