//! The MNI152 rows: the real brain (fixtures/mni152) with the default solver, its craniotomy
//! pushed over the clinical range of brain shift (issue 23: shifts of up to 10 mm are
//! common and up to 25 mm happen), and the same brain nearly incompressible (ν up to
//! 0.4999, κ/μ up to 5000) with the time of each solve against ν = 0.49's in the same run.

use crate::study::Variant;
use bs_scene::Prepared;
use bs_scene::scene::{ElementChoice, SolverKind};

use super::Cell;
use super::measure::{measure, measured_cell};
use crate::util::root;

/// The scene's own craniotomy displacement (mm, along −z).
const SCENE_DEPTH: f64 = 8.0;

/// The pushes of the clinical-range row (mm).
pub const DEPTHS: [f64; 6] = [4.0, 8.0, 12.0, 16.0, 20.0, 25.0];

/// Poisson's ratios of the incompressibility row.
pub const POISSON: [f64; 3] = [0.49, 0.499, 0.4999];

fn mni152() -> Result<Prepared, String> {
    let path = root().join("fixtures/mni152/scene.toml");
    Prepared::load(&path).map_err(|e| format!("{}: {e}", path.display()))
}

/// κ/μ of a Poisson's ratio: 2(1 + ν) / (3(1 − 2ν)).
pub fn bulk_to_shear(nu: f64) -> f64 {
    2.0 * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu))
}

/// The craniotomy pushed 4…25 mm, Newton–Krylov (the default solver).
pub fn craniotomy(cells: &mut Vec<Cell>) -> Result<(), String> {
    let p = mni152()?;
    let row = "MNI152 craniotomy (clinical range), Newton-Krylov";
    for depth in DEPTHS {
        let v = Variant {
            solver: Some(SolverKind::NewtonKrylov),
            load_factor: Some(depth / SCENE_DEPTH),
            ..Variant::default()
        };
        let m = measure(&v, &p);
        cells.push(measured_cell(row, format!("{depth} mm"), &m, Some(depth), String::new()));
    }
    Ok(())
}

/// T4ANP at ν = 0.49, 0.499, 0.4999, Newton–Krylov: outcome, iterations, GMRES iterations
/// per Newton iteration (the preconditioner's quality as κ/μ grows) and the solve time
/// against ν = 0.49's.
pub fn poisson(cells: &mut Vec<Cell>) -> Result<(), String> {
    let p = mni152()?;
    let row = "Poisson's ratio, MNI152, Newton-Krylov";
    let mut base = None;
    for nu in POISSON {
        let v = Variant {
            element: Some(ElementChoice::T4anp),
            solver: Some(SolverKind::NewtonKrylov),
            poisson_ratio: Some(nu),
            ..Variant::default()
        };
        let m = measure(&v, &p);
        let seconds = m.result.as_ref().ok().map(|o| o.solve_seconds);
        if nu == POISSON[0] {
            base = seconds;
        }
        let note = match (seconds, base) {
            (Some(s), Some(b)) if nu != POISSON[0] => format!("solve {:.2}x the 0.49 time", s / b),
            _ => String::new(),
        };
        let value = format!("{nu} (κ/μ {:.0})", bulk_to_shear(nu));
        cells.push(measured_cell(row, value, &m, None, note));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// κ/μ from ν against μ = E/(2(1+ν)), κ = E/(3(1−2ν)) (the scene's conversion): the
    /// issue's 50, 500, 5000.
    #[test]
    fn bulk_to_shear_ratios() {
        for (nu, ratio) in [(0.49, 49.67), (0.499, 499.67), (0.4999, 4999.67)] {
            assert!((bulk_to_shear(nu) - ratio).abs() < 0.01, "{nu}");
        }
    }
}
