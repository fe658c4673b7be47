//! Gravity's unknowns as a parameter vector: a shift of the fluid's level along gravity,
//! two small tilts of its direction, and a factor on the weight, each with its prior's
//! standard deviation. `θ = 0` is the scene's `[gravity]`; [`Unknowns::gravity_at`] maps any
//! `θ` to the `[gravity]` it stands for.

use bs_mesh::Vector3;

use crate::scene::{Estimate, Gravity};

/// One scalar unknown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Param {
    /// The level's shift along the scene's gravity (mesh units; positive: deeper, more of
    /// the brain drained).
    Level,
    /// A tilt of the direction towards the first (second) axis normal to it (radians).
    TiltA,
    TiltB,
    /// The weight's relative change (the acceleration times `1 + θ`).
    Weight,
}

/// The weight's factor never falls below this (a brain that weighs nothing has no level).
const MIN_WEIGHT_FACTOR: f64 = 0.1;

/// The unknowns a scene's `estimate` names, around its `[gravity]`.
#[derive(Debug, Clone)]
pub(crate) struct Unknowns {
    pub params: Vec<Param>,
    /// Prior standard deviations, in the parameters' units.
    pub prior_sd: Vec<f64>,
    base: Gravity,
    down: Vector3<f64>,
    axes: [Vector3<f64>; 2],
}

impl Unknowns {
    /// The unknowns of `estimate` around `gravity` (checked: a unit direction exists).
    pub fn new(gravity: &Gravity, estimate: &Estimate) -> Unknowns {
        let down = Vector3::from(gravity.unit().expect("validated [gravity] direction"));
        let mut params = Vec::new();
        let mut prior_sd = Vec::new();
        if let Some(sd) = estimate.level {
            params.push(Param::Level);
            prior_sd.push(sd);
        }
        if let Some(deg) = estimate.direction {
            params.extend([Param::TiltA, Param::TiltB]);
            prior_sd.extend([deg.to_radians(); 2]);
        }
        if let Some(sd) = estimate.weight {
            params.push(Param::Weight);
            prior_sd.push(sd);
        }
        Unknowns { params, prior_sd, base: gravity.clone(), down, axes: normal_axes(down) }
    }

    /// The `[gravity]` of parameters `theta` (without its `estimate`).
    pub fn gravity_at(&self, theta: &[f64]) -> Gravity {
        let mut g = self.base.clone();
        g.estimate = None;
        let mut down = self.down;
        for (p, &t) in self.params.iter().zip(theta) {
            match p {
                Param::Level => {
                    if let Some(f) = &mut g.fluid {
                        f.level = (Vector3::from(f.level) + self.down * t).into();
                    }
                }
                Param::TiltA => down += self.axes[0] * t,
                Param::TiltB => down += self.axes[1] * t,
                Param::Weight => g.acceleration *= (1.0 + t).max(MIN_WEIGHT_FACTOR),
            }
        }
        g.direction = down.normalize().into();
        g
    }

    /// The finite-difference step of each parameter: a millimetre of level (in mesh units
    /// `mm`), half a degree, 3 % of the weight; never above a third of the prior.
    pub fn probes(&self, mm: f64) -> Vec<f64> {
        self.params
            .iter()
            .zip(&self.prior_sd)
            .map(|(p, &sd)| {
                let h = match p {
                    Param::Level => mm,
                    Param::TiltA | Param::TiltB => 0.5f64.to_radians(),
                    Param::Weight => 0.03,
                };
                h.min(sd / 3.0)
            })
            .collect()
    }

    /// The angle (radians) between gravity at `theta` and the scene's.
    pub fn tilt(&self, theta: &[f64]) -> f64 {
        let d = Vector3::from(self.gravity_at(theta).direction);
        d.dot(&self.down).clamp(-1.0, 1.0).acos()
    }
}

/// Two unit axes normal to `n` and to each other.
fn normal_axes(n: Vector3<f64>) -> [Vector3<f64>; 2] {
    let pick = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let a = (pick - n * n.dot(&pick)).normalize();
    [a, n.cross(&a)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Fluid;

    fn gravity() -> Gravity {
        Gravity {
            direction: [0.0, -2.0, 0.0],
            acceleration: 9.81,
            fluid: Some(Fluid { density: 1007.0, level: [1.0, 2.0, 3.0] }),
            estimate: None,
        }
    }

    #[test]
    fn zero_is_the_scene_and_each_parameter_moves_what_it_names() {
        let e = Estimate { level: Some(15.0), direction: Some(5.0), weight: Some(0.3) };
        let u = Unknowns::new(&gravity(), &e);
        assert_eq!(u.params, [Param::Level, Param::TiltA, Param::TiltB, Param::Weight]);
        assert!((u.prior_sd[1] - 5f64.to_radians()).abs() < 1e-15);
        let g0 = u.gravity_at(&[0.0; 4]);
        assert_eq!(g0.direction, [0.0, -1.0, 0.0]);
        assert_eq!(g0.fluid.unwrap().level, [1.0, 2.0, 3.0]);
        // 10 mm deeper along gravity (−y), a 30 % heavier brain.
        let g = u.gravity_at(&[10.0, 0.0, 0.0, 0.3]);
        assert_eq!(g.fluid.unwrap().level, [1.0, -8.0, 3.0]);
        assert!((g.acceleration - 9.81 * 1.3).abs() < 1e-12);
        // A tilt of t radians turns the direction by atan(t), about an axis normal to it.
        let t = 0.1f64;
        for theta in [[0.0, t, 0.0, 0.0], [0.0, 0.0, t, 0.0]] {
            assert!((u.tilt(&theta) - t.atan()).abs() < 1e-12);
        }
        let (a, b) = (u.gravity_at(&[0.0, t, 0.0, 0.0]), u.gravity_at(&[0.0, 0.0, t, 0.0]));
        let (da, db) = (Vector3::from(a.direction), Vector3::from(b.direction));
        let down = Vector3::new(0.0, -1.0, 0.0);
        // The two tilts are perpendicular.
        assert!((da - down * da.dot(&down)).dot(&(db - down * db.dot(&down))).abs() < 1e-12);
    }
}
