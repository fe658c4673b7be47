//! The quick validation cases — closed forms, DR against Newton–Krylov, contact queries
//! against brute force — each within its row's tolerance (the same rows `cargo xtask
//! validate --quick` prints; the full set, with CalculiX, is `cargo xtask validate`).

use bs_study::validate::{Scope, run};

#[test]
fn quick_validation_cases_pass() {
    let rows = run(Scope::Quick).unwrap();
    assert!(rows.len() >= 6 + 1 + 18, "{} rows", rows.len());
    let failed: Vec<_> = rows.iter().filter(|r| !r.pass()).collect();
    assert!(failed.is_empty(), "{failed:#?}");
}
