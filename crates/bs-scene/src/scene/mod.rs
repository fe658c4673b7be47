//! Scene files: what a user (or a validation script) writes to describe one brain-shift
//! computation. The keys are a contract: extend, never rename.
//!
//! ```toml
//! units = "mm"
//! space = "RAS"            # or "LPS"; the frame of the mesh (default RAS)
//! [mesh]
//! file = "brain.inp"
//! element = "t4anp"
//! [[region]]
//! elset = "BRAIN"
//! material = { model = "neo-hookean", youngs_modulus = 3000.0, poisson_ratio = 0.49, density = 1000.0 }
//! [[boundary]]
//! nset = "FIXED"
//! fix = ["x", "y", "z"]
//! [[boundary]]
//! nset = "CRANIOTOMY"
//! displacement = { x = 0.0, y = 0.0, z = -8.0 }
//! [contact]
//! skull = "skull.stl"
//! algorithm = "paper"
//! [solver]
//! kind = "dr"
//! tolerance = 1e-3
//! [output]
//! surfaces = ["VENTRICLES"]   # deformed boundary of these element sets (VTK, STL)
//! ```
//!
//! Paths are relative to the scene file. Unknown keys are errors (a misspelt key must not be
//! silently ignored).

/// Each name enum displays as the scene file spells it.
macro_rules! display_by_name {
    ($($t:ty),*) => {$(
        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
    )*};
}

mod boundary;
mod file;
mod frame;
mod gravity;
mod material;
mod measurement;
mod solver;
mod uncertainty;

pub use boundary::*;
pub use file::*;
pub use frame::*;
pub use gravity::*;
pub use material::*;
pub use measurement::*;
pub use solver::*;
pub use uncertainty::*;

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
units = "mm"
space = "RAS"
[mesh]
file = "brain.inp"
element = "t4anp"
[[region]]
elset = "BRAIN"
material = { model = "neo-hookean", youngs_modulus = 3000.0, poisson_ratio = 0.49, density = 1000.0 }
[[boundary]]
nset = "FIXED"
fix = ["x", "y", "z"]
[[boundary]]
nset = "CRANIOTOMY"
displacement = { x = 0.0, y = 0.0, z = -8.0 }
[contact]
skull = "skull.stl"
algorithm = "paper"
[solver]
kind = "dr"
tolerance = 1e-3
"#;

    #[test]
    fn the_documented_example_parses() {
        let s = Scene::parse(GOOD).unwrap();
        assert_eq!(s.units, Units::Mm);
        assert_eq!(s.mesh.element, Some(ElementChoice::T4anp));
        let m = s.regions[0].material.moduli().unwrap();
        // E = 3000, nu = 0.49: mu = E / 2(1+nu), kappa = E / 3(1-2nu).
        approx::assert_relative_eq!(m.mu, 3000.0 / 2.98, epsilon = 1e-12);
        approx::assert_relative_eq!(m.kappa, 3000.0 / 0.06, epsilon = 1e-9);
        assert_eq!(
            s.boundaries[1].displacement.unwrap().components(),
            [Some(0.0), Some(0.0), Some(-8.0)]
        );
        assert_eq!(s.contact.unwrap().algorithm, Algorithm::Paper);
        assert_eq!(
            s.solver,
            Solver { kind: SolverKind::Dr, tolerance: 1e-3, ramp_steps: 200, max_steps: None }
        );
    }

    #[test]
    fn a_misspelt_key_is_an_error_naming_it_and_its_line() {
        let bad = GOOD.replace("tolerance = 1e-3", "tolerence = 1e-3");
        let e = Scene::parse(&bad).unwrap_err();
        assert!(e.contains("tolerence"), "{e}");
        assert!(e.contains("line 21"), "{e}");
    }

    #[test]
    fn range_and_exclusivity_mistakes_are_errors() {
        let cases = [
            ("poisson_ratio = 0.49", "poisson_ratio = 0.5", "poisson_ratio must lie in (-1, 0.5)"),
            ("youngs_modulus = 3000.0", "youngs_modulus = -3.0", "youngs_modulus must be positive"),
            ("fix = [\"x\", \"y\", \"z\"]", "fix = [\"x\", \"w\"]", "unknown variant `w`"),
            ("units = \"mm\"", "units = \"cm\"", "unknown variant `cm`"),
            ("kind = \"dr\"", "kind = \"explicit\"", "unknown variant `explicit`"),
            ("tolerance = 1e-3", "tolerance = 0.0", "tolerance must be positive"),
            ("z = -8.0 }", "z = -8.0 }\nfix = [\"x\"]", "exactly one of fix, displacement"),
            ("model = \"neo-hookean\"", "model = \"ogden\"", "needs alpha"),
            ("algorithm = \"paper\"", "algorithm = \"none\"", "remove the [contact] table"),
            ("algorithm = \"paper\"", "algorithm = \"fast\"", "unknown variant `fast`"),
            ("space = \"RAS\"", "space = \"ras\"", "space \"ras\" is not a frame brainshift knows"),
        ];
        for (from, to, expect) in cases {
            let e = Scene::parse(&GOOD.replace(from, to)).unwrap_err();
            assert!(e.contains(expect), "{to}: {e}");
        }
    }

    #[test]
    fn defaults_apply_when_optional_tables_are_missing() {
        let s = Scene::parse(
            "units = \"m\"\n[mesh]\nfile = \"a.msh\"\n[[region]]\nelset = \"*\"\n\
             material = { model = \"svk\", shear_modulus = 1000.0, bulk_modulus = 50000.0 }\n",
        )
        .unwrap();
        assert_eq!(s.solver, Solver::default());
        assert_eq!(s.contact, None);
        assert_eq!(s.regions[0].material.density, None);
        assert_eq!(s.regions[0].material.density_or_default(), DEFAULT_DENSITY);
        assert_eq!(s.units, Units::M);
    }
}
