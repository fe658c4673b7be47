//! A row of the validation table, the scope of a run, and the loading and solving every case
//! shares.

use crate::study::{Outcome, Variant};
use crate::util::root;
use bs_scene::Prepared;

/// One line of the validation table.
#[derive(Debug, Clone)]
pub struct Row {
    /// Group and case, e.g. `closed form / uniaxial t4`.
    pub case: String,
    /// What is measured.
    pub quantity: String,
    /// Measured value.
    pub value: f64,
    /// Largest acceptable value.
    pub tolerance: f64,
    /// Unit of value and tolerance.
    pub unit: &'static str,
}

impl Row {
    /// Whether the value is within the tolerance (NaN never passes).
    pub fn pass(&self) -> bool {
        self.value <= self.tolerance
    }
}

/// Which cases to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// The cases that take seconds in a debug build (`cargo test`).
    Quick,
    /// Everything (release).
    Full,
}

pub(super) fn load(rel: &str) -> Result<Prepared, String> {
    Prepared::load(&root().join(rel)).map_err(|e| format!("{rel}: {e}"))
}

pub(super) fn solve(p: &Prepared, v: &Variant, what: &str) -> Result<Outcome, String> {
    v.solve(p).map_err(|e| format!("{what}: {e}"))
}

/// One row as `validate` prints it while measuring.
pub(super) fn print_row(r: &Row) {
    println!(
        "{:<46} {:<40} {:>11.3e} {:>10.1e} {:<3} {}",
        r.case,
        r.quantity,
        r.value,
        r.tolerance,
        r.unit,
        if r.pass() { "pass" } else { "FAIL" }
    );
}
