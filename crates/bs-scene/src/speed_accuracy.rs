//! The speed-against-accuracy findings `brainshift check` advises from: per benchmark case,
//! the cheapest configuration that met each accuracy target ([`Findings`]), as
//! `cargo xtask chart` (bs-study) writes them to `data/speed-accuracy.json`, embedded here
//! at build time.

use serde::{Deserialize, Serialize};

const DATA: &str = include_str!("../data/speed-accuracy.json");

/// The chart's findings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Findings {
    /// The command that wrote them.
    #[serde(default)]
    pub generated_by: String,
    /// What the targets mean.
    #[serde(default)]
    pub note: String,
    /// One entry per benchmark case.
    pub cases: Vec<CaseFindings>,
}

/// The findings of one benchmark case.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseFindings {
    /// Case name.
    pub case: String,
    /// Mean element edge of the case's finest mesh (mm).
    pub reference_mean_edge_mm: f64,
    /// Bounding-box diagonal of the case's brain (mm).
    pub diagonal_mm: f64,
    /// Wall time of the reference solution (s).
    #[serde(default)]
    pub reference_seconds: f64,
    /// The cheapest configuration per accuracy target.
    pub targets: Vec<Target>,
}

/// The cheapest configuration that met one mean-error target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Target {
    /// Mean nodal error target (mm).
    pub target_mm: f64,
    /// Element technology (`t4`, `t4anp`).
    pub element: String,
    /// Solver (`newton-krylov`, `dr`); findings written before the Newton–Krylov solver
    /// existed have none (they were DR).
    #[serde(default = "dr")]
    pub solver: String,
    /// Contact handler (`none` without skull).
    #[serde(default)]
    pub handler: String,
    /// Solver tolerance (mm).
    pub tolerance_mm: f64,
    /// Mean element edge of its mesh (mm).
    pub mean_edge_mm: f64,
    /// Its wall time on the benchmark machine (s).
    pub seconds: f64,
    /// Its measured mean error (mm).
    pub mean_error_mm: f64,
    /// Its largest nodal error (mm): at the rim of the prescribed patch, where each mesh
    /// resolves the boundary of the set differently.
    pub max_error_mm: f64,
    /// Mesh level label (`coarse`, `default`, `fine`, …).
    #[serde(default)]
    pub level: String,
}

fn dr() -> String {
    "dr".into()
}

impl Findings {
    /// The findings embedded in this build.
    pub fn embedded() -> Result<Findings, String> {
        serde_json::from_str(DATA).map_err(|e| format!("embedded speed-accuracy findings: {e}"))
    }
}
