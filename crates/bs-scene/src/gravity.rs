//! The scene's `[gravity]` as the solver's body force: each region's weight per unit
//! reference volume in the model's units, and the fluid that buoys the tissue below its
//! level.
//!
//! Units: densities in kg/m³ and the acceleration in m/s² give `ρ g` in N/m³ = Pa/m; the
//! model's stresses are in Pa and its lengths in the scene's unit, so the force per unit
//! volume is `ρ g` times the metres per length unit (Pa/mm = 10⁻³ Pa/m); nodal forces
//! then come out in Pa·mm² (µN) for a scene in millimetres.

use bs_dr::{BodyForce, Buoyancy, Model};
use bs_mesh::{Point3, Vector3};

use crate::SceneError;
use crate::prepare::Prepared;
use crate::scene::{Gravity, Scene};

/// The body force of a scene with `gravity` (direction `direction` instead of the scene's
/// when given: a head turned during surgery), checked against the mesh: a fluid level
/// entirely above or below the brain is an error saying what it would mean.
pub fn body_force(p: &Prepared, gravity: &Gravity) -> Result<BodyForce, SceneError> {
    let err = |message: String| SceneError::Scene { file: p.path.clone(), message };
    let unit = gravity.unit().ok_or_else(|| {
        err(format!(
            "[gravity] direction {:?} has no direction: give a non-zero vector",
            gravity.direction
        ))
    })?;
    let down = Vector3::from(unit);
    let per_metre = p.scene.units.metres();
    let g = down * gravity.acceleration * per_metre;
    let per_solid = p.scene.regions.iter().map(|r| g * r.material.density_or_default()).collect();
    let buoyancy = match &gravity.fluid {
        None => None,
        Some(f) => {
            let level = Point3::from(f.level);
            check_level(p, &p.scene, level, down).map_err(err)?;
            Some(Buoyancy { per_volume: -g * f.density, level, down })
        }
    };
    Ok(BodyForce { per_solid, buoyancy })
}

/// A level with brain on both sides, or what a level beside the brain would mean.
fn check_level(
    p: &Prepared,
    scene: &Scene,
    level: Point3<f64>,
    down: Vector3<f64>,
) -> Result<(), String> {
    let depth = |x: &Point3<f64>| down.dot(&(x - level));
    let (lo, hi) = p.mesh.nodes.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        (lo.min(depth(x)), hi.max(depth(x)))
    });
    let unit = scene.units.symbol();
    if lo > 0.0 {
        return Err(format!(
            "[gravity] fluid.level {:?} lies {lo:.1} {unit} above the brain's highest point \
             (along gravity): the whole brain would be submerged, nothing drained. Put the \
             level where the fluid's surface is, on the brain (depths span {:.1} {unit}), or, \
             for a brain floating in undrained fluid, say so by a level at its top",
            level.coords.as_slice(),
            hi - lo
        ));
    }
    if hi <= 0.0 {
        return Err(format!(
            "[gravity] fluid.level {:?} lies {:.1} {unit} below the brain's lowest point \
             (along gravity): no tissue would be submerged and the fluid would change nothing. \
             Remove `fluid` if all of it drained, or raise the level onto the brain",
            level.coords.as_slice(),
            -hi
        ));
    }
    Ok(())
}

/// The consistent nodal loads of `gravity` (the scene's, or an estimate's) on `model`.
pub fn nodal_loads_with(
    p: &Prepared,
    model: &Model,
    gravity: &Gravity,
) -> Result<Vec<Vector3<f64>>, SceneError> {
    let body = body_force(p, gravity)?;
    model
        .body_loads(&body)
        .map_err(|e| SceneError::Scene { file: p.path.clone(), message: e.to_string() })
}
