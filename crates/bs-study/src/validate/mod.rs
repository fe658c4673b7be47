//! `cargo xtask validate`: every reference case, one table (case, quantity, value,
//! tolerance, pass), written to `docs/validation.md`; non-zero exit if any case fails.
//!
//! Cases:
//! * homogeneous closed forms (uniaxial compression, simple shear) for T4, T4ANP and H8;
//! * a confined column under its own weight, dry and half submerged, against its closed
//!   form on T4ANP and H8 at three refinements;
//! * Dynamic Relaxation against Newton on the same mesh;
//! * every contact handler against brute force, as closest-point queries on the property
//!   surfaces and as whole contact solves;
//! * DR + kinematic contact against the stored CalculiX references (`cargo xtask reference`).
//!
//! Every tolerance is derived from the physics or the numerics of the case (documented next
//! to it), never from what the code happens to produce. The quick cases run in `cargo test`;
//! the whole set runs optimised (`cargo xtask validate` re-runs itself in release).

use std::fmt::Write as _;

use crate::util::{escape_cell, replace_block, root};

mod calculix;
mod cases;
mod row;

pub use calculix::{CCX_DR_TOLERANCE, facet_allowance};
pub use row::{Row, Scope};

use calculix::{
    calculix, calculix_cases, calculix_gravity, calculix_held, calculix_without_contact_case,
};
use cases::{
    closed_forms, determinism, dr_vs_newton, gravity_column, handler_queries, handler_solves,
    paper_40mm,
};
use row::print_row;

/// Runs the cases of `scope`, printing each row as it is measured.
pub fn run(scope: Scope) -> Result<Vec<Row>, String> {
    let mut rows = Vec::new();
    let mut add = |r: Row| {
        print_row(&r);
        rows.push(r);
    };
    closed_forms(&mut add)?;
    gravity_column(&mut add, scope)?;
    dr_vs_newton(&mut add)?;
    handler_queries(&mut add)?;
    if scope == Scope::Full {
        paper_40mm(&mut add)?;
        handler_solves(&mut add)?;
        calculix(&mut add)?;
        determinism(&mut add)?;
    }
    Ok(rows)
}

/// The table as Markdown.
pub fn markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| case | quantity | value | tolerance | unit | pass |\n|---|---|---:|---:|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3e} | {:.1e} | {} | {} |",
            escape_cell(&r.case),
            escape_cell(&r.quantity),
            r.value,
            r.tolerance,
            r.unit,
            if r.pass() { "pass" } else { "**FAIL**" }
        );
    }
    s
}

/// What `cargo xtask validate` runs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Options {
    /// Every case (or the quick ones) in one table.
    Table(Scope),
    /// One CalculiX case alone, printed: a fixture with stored references,
    /// `ellipsoid-gravity` or `regions-held`.
    Calculix(String),
}

/// `cargo xtask validate [--quick]`: all cases (or the quick ones), the table written into
/// docs/validation.md between its markers (full run only); error if any case fails.
pub fn main(o: &Options) -> Result<(), String> {
    let scope = match o {
        Options::Table(scope) => *scope,
        Options::Calculix(case) => {
            // One CalculiX case alone, printed, docs/validation.md untouched.
            let mut failed = 0;
            let mut print = |r: Row| {
                print_row(&r);
                failed += usize::from(!r.pass());
            };
            if case == "ellipsoid-gravity" {
                calculix_gravity(&mut print)?;
            } else if case == "regions-held" {
                calculix_held(&mut print)?;
            } else {
                calculix_without_contact_case(&mut print, case)?;
                calculix_cases(&mut print, &[case.as_str()])?;
            }
            return if failed == 0 { Ok(()) } else { Err(format!("{failed} case(s) failed")) };
        }
    };
    let rows = run(scope)?;
    if scope == Scope::Quick {
        let failed = rows.iter().filter(|r| !r.pass()).count();
        println!("{} quick cases, {failed} failed", rows.len());
        return if failed == 0 { Ok(()) } else { Err(format!("{failed} case(s) failed")) };
    }
    let table = markdown(&rows);
    let path = root().join("docs/validation.md");
    replace_block(&path, "table", &table)?;
    let failed = rows.iter().filter(|r| !r.pass()).count();
    println!("{} cases, {failed} failed; table written to {}", rows.len(), path.display());
    if failed > 0 {
        return Err(format!("{failed} validation case(s) outside tolerance"));
    }
    Ok(())
}
