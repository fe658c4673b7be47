//! The stability map's quick rows (the block cases of `cargo xtask stability --quick`): no
//! run fails silently, and the guards stop the runs theory says must stop.

use bs_study::stability::{Scope, run};
use bs_study::verdict::Verdict;

/// The quick rows: every run either converges or is stopped by a guard, never returns
/// an invalid result; and the guards are the expected ones where theory says so.
#[test]
fn quick_rows_never_fail_silently() {
    let cells = run(Scope::Quick).unwrap();
    let silent: Vec<_> =
        cells.iter().filter(|c| !c.ablation && matches!(c.verdict, Verdict::Silent(_))).collect();
    assert!(silent.is_empty(), "{silent:#?}");
    let get = |row: &str, value: &str| {
        cells.iter().find(|c| c.row.starts_with(row) && c.value == value).map(|c| c.verdict.clone())
    };
    // Below the element bound DR is stable; at 3× it (≈ 1.9× the true critical step on
    // this mesh) it must be stopped as unstable.
    assert_eq!(get("DR time step", "0.5x"), Some(Verdict::Converged));
    assert_eq!(get("DR time step", "0.8x"), Some(Verdict::Converged));
    assert!(
        matches!(get("DR time step", "3x"), Some(Verdict::Guard(g)) if g != "ContactCheck"),
        "{cells:#?}"
    );
    // Newton–Krylov converges however loosely its linear systems are solved.
    for eta in ["0.01", "0.1", "0.5", "0.9"] {
        assert_eq!(get("Newton-Krylov forcing", eta), Some(Verdict::Converged), "{eta}");
    }
    // A 40 mm block indented 34 mm by a 20 mm patch: DR's explicit ramp inverts an
    // element; Newton–Krylov, whose steps never invert one and whose load steps are cut
    // back instead, reaches the equilibrium (verified: residual, every J > 0), which the
    // energy's J → 0 barrier guarantees exists. The DR failure is the solver's, not the
    // mesh's.
    assert!(
        matches!(get("indentation depth (40 mm block), DR", "34 mm"), Some(Verdict::Guard(g)) if g == "ElementInverted"),
        "{cells:#?}"
    );
    for depth in ["24 mm", "30 mm", "34 mm"] {
        assert_eq!(
            get("indentation depth (40 mm block), Newton-Krylov", depth),
            Some(Verdict::Converged),
            "{depth}: {cells:#?}"
        );
    }
    // T4ANP does not lock: both solvers converge up to ν = 0.499.
    for solver in ["DR", "Newton-Krylov"] {
        for nu in ["0.45", "0.49", "0.495", "0.499"] {
            let row = format!("Poisson ratio, T4ANP, {solver}");
            assert_eq!(get(&row, nu), Some(Verdict::Converged), "{solver} {nu}");
        }
    }
    for solver in ["DR", "Newton-Krylov"] {
        let indentation = format!("indentation depth (40 mm block), {solver}");
        assert_eq!(get(&indentation, "8 mm"), Some(Verdict::Converged), "{solver}");
        // With the lists the paper handler finds every penetration at the box's corners.
        let corners = format!("sharp corners (box skull), {solver}");
        assert_eq!(get(&corners, "lists on"), Some(Verdict::Converged), "{solver}");
        assert_eq!(get(&corners, "brute force"), Some(Verdict::Converged), "{solver}");
        // Without them it misplaces nodes; that must be stopped (DR: the misplaced nodes
        // invert an element; Newton–Krylov: its active set never settles), never
        // returned.
        assert!(
            matches!(get(&corners, "lists off"), Some(Verdict::Guard(_))),
            "{solver}: {cells:#?}"
        );
    }
}
