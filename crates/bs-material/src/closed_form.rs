//! Closed-form homogeneous states of the laws here: independent expectations for the
//! patch tests of the finite-element code (bs-cli's tests, `cargo xtask validate`).
//!
//! Each formula is written out here from the law's energy, not evaluated through the law's
//! kernels, so that a test comparing the two can fail.

use crate::material::Material;

/// Lateral stretch `l` of a decoupled Neo-Hookean body in uniaxial stress with axial stretch
/// `lambda` (shear modulus `mu`, bulk modulus `kappa`): the root of the lateral Cauchy stress
/// σ₂₂ = (μ/J)(λ̄₂² − Ī₁/3) + κ(J − 1) = 0 with J = l²λ and λ̄ᵢ = J^(−1/3)λᵢ, by bisection
/// to machine precision. `None` if the root is not bracketed in (0.2, 5) (absurd input).
pub fn neo_hookean_uniaxial_lateral_stretch(lambda: f64, mu: f64, kappa: f64) -> Option<f64> {
    let sigma = |l: f64| {
        let j = l * l * lambda;
        let s = j.powf(-2.0 / 3.0);
        let i1 = s * (2.0 * l * l + lambda * lambda);
        mu / j * (s * l * l - i1 / 3.0) + kappa * (j - 1.0)
    };
    let (mut lo, mut hi) = (0.2, 5.0);
    if !(sigma(lo) < 0.0 && sigma(hi) > 0.0) {
        return None;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if sigma(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// Axial first Piola–Kirchhoff stress `P₃₃` of a confined (uniaxial strain) state
/// `F = diag(1, 1, λ)`, written out from the law's energy; `None` for laws this module has no
/// closed form for (Ogden).
///
/// * Neo-Hookean, `W = μ/2 (J^(−2/3) I₁ − 3) + κ/2 (J − 1)²` with `J = λ`, `I₁ = 2 + λ²`:
///   `P₃₃ = ∂W/∂λ = (2μ/3) λ^(−5/3) (λ² − 1) + κ (λ − 1)`, increasing for every λ > 0.
/// * St Venant–Kirchhoff, `W = λₗ/2 (tr E)² + μ E:E` with `E₃₃ = (λ² − 1)/2` the only strain:
///   `P₃₃ = λ S₃₃ = (λₗ + 2μ) λ (λ² − 1)/2`, increasing for λ > 1/√3 (below, the law
///   softens: the compressive branch the solver must not reach).
pub fn confined_axial_pk1(material: &Material, lambda: f64) -> Option<f64> {
    match material {
        Material::NeoHookean(e) => Some(
            2.0 * e.mu / 3.0 * lambda.powf(-5.0 / 3.0) * (lambda * lambda - 1.0)
                + e.kappa * (lambda - 1.0),
        ),
        Material::StVenantKirchhoff(l) => {
            Some((l.lambda + 2.0 * l.mu) * lambda * (lambda * lambda - 1.0) / 2.0)
        }
        Material::Ogden(_) => None,
    }
}

/// The axial stretch of a confined state with axial first Piola–Kirchhoff stress `p`: the
/// root of [`confined_axial_pk1`] on its stable branch, by bisection to machine precision;
/// `None` for a law without a closed form or a stress outside (−10⁶, 10⁶)·P(2).
pub fn confined_stretch(material: &Material, p: f64) -> Option<f64> {
    let floor = confined_stable_floor(material)?;
    let (mut lo, mut hi) = (floor + 1e-12, 2.0);
    let pk1 = |l: f64| confined_axial_pk1(material, l).unwrap_or(f64::NAN);
    while pk1(hi) < p {
        hi *= 2.0;
        if hi > 1e6 {
            return None;
        }
    }
    if pk1(lo).is_nan() || pk1(lo) > p {
        return None;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if pk1(mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// A column `0 ≤ Z ≤ height` confined laterally (rollers on its sides, so every section
/// deforms as `F = diag(1, 1, λ(Z))`), held at `Z = 0`, under a body force per unit
/// reference volume `weight(Z)` pointing to −Z (its own weight, less a fluid's buoyancy
/// where it is submerged) and the axial first Piola–Kirchhoff stress `top` at its top (0: a
/// free top; negative: pressed down): the axial displacements `u(Z)` at the heights `z`.
///
/// Equilibrium of the part above `Z`: `P₃₃(Z) = top − ∫_Z^H weight`, so `λ(Z)` is
/// [`confined_stretch`] of it and `u(Z) = ∫_0^Z (λ − 1)`. Both integrals by the trapezoid
/// rule on 2¹⁴ intervals (a jump of `weight` on a grid point, such as a fluid level at a
/// dyadic fraction of the height, is integrated exactly; the second integral's error is of
/// order `(H/2¹⁴)² λ''`, below 10⁻⁸ of the settlement here), then linear interpolation.
/// `None` without a closed form.
pub fn confined_column_displacement(
    material: &Material,
    height: f64,
    weight: &dyn Fn(f64) -> f64,
    top: f64,
    z: &[f64],
) -> Option<Vec<f64>> {
    let n = 1 << 14;
    let dz = height / n as f64;
    // The weight of each interval taken at its midpoint (exact for piecewise constants
    // jumping on grid points).
    let mut p = vec![top; n + 1];
    for i in (0..n).rev() {
        p[i] = p[i + 1] - weight((i as f64 + 0.5) * dz) * dz;
    }
    let stretch: Vec<f64> =
        p.iter().map(|&pi| confined_stretch(material, pi)).collect::<Option<_>>()?;
    let mut u = vec![0.0; n + 1];
    for i in 1..=n {
        u[i] = u[i - 1] + 0.5 * (stretch[i - 1] + stretch[i] - 2.0) * dz;
    }
    Some(
        z.iter()
            .map(|&zi| {
                let t = (zi / dz).clamp(0.0, n as f64);
                let i = (t.floor() as usize).min(n - 1);
                u[i] + (t - i as f64) * (u[i + 1] - u[i])
            })
            .collect(),
    )
}

/// The smallest axial stretch on the increasing (stable) branch of [`confined_axial_pk1`].
fn confined_stable_floor(material: &Material) -> Option<f64> {
    match material {
        Material::NeoHookean(_) => Some(0.0),
        Material::StVenantKirchhoff(_) => Some(1.0 / 3f64.sqrt()),
        Material::Ogden(_) => None,
    }
}

/// Two bars in series along their axis, each confined laterally (rollers: no lateral
/// displacement, so each deforms homogeneously as `diag(1, 1, λᵢ)`), one end held, the other
/// shortened by `shortening`: the axial stretches `[λ₁, λ₂]` of the bars of reference lengths
/// `first.1` and `second.1`.
///
/// Equilibrium of the series: the same axial first Piola–Kirchhoff stress (force per
/// reference area, the same cross-section) in both, `P₁(λ₁) = P₂(λ₂)`, and compatibility
/// `L₁ λ₁ + L₂ λ₂ = L₁ + L₂ − d`. Eliminating λ₂ leaves `P₁(λ₁) − P₂((L − d − L₁λ₁)/L₂)`,
/// increasing in λ₁ on the stable branches, whose root is found by bisection to machine
/// precision. `None` for a law without a closed form (Ogden), non-positive lengths, or a
/// shortening that leaves no state on both stable branches.
pub fn confined_series_stretches(
    first: (&Material, f64),
    second: (&Material, f64),
    shortening: f64,
) -> Option<[f64; 2]> {
    let ((m1, l1), (m2, l2)) = (first, second);
    if !(l1 > 0.0 && l2 > 0.0 && shortening.is_finite()) {
        return None;
    }
    let length = l1 + l2 - shortening;
    let second_stretch = |s1: f64| (length - l1 * s1) / l2;
    let g =
        |s1: f64| Some(confined_axial_pk1(m1, s1)? - confined_axial_pk1(m2, second_stretch(s1))?);
    let lo0 = confined_stable_floor(m1)?;
    let hi0 = (length - l2 * confined_stable_floor(m2)?) / l1;
    // Open interval: step inside both ends so that neither stretch is at its floor.
    let (mut lo, mut hi) = (lo0 + 1e-12 * (hi0 - lo0), hi0 - 1e-12 * (hi0 - lo0));
    if !(lo < hi && g(lo)? < 0.0 && g(hi)? > 0.0) {
        return None;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if g(mid)? < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let s1 = 0.5 * (lo + hi);
    Some([s1, second_stretch(s1)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_column_under_its_own_weight_settles_as_linear_elasticity_says_when_light() {
        // Small strain: λ − 1 = P / M (M the P-wave modulus) with P = −w (H − Z), so
        // u(H) = −w H² / (2M).
        let m = Material::neo_hookean(3000.0, 0.45).unwrap();
        let big_m = m.elastic().p_wave_modulus();
        let (w, h) = (1e-3, 50.0);
        let u = confined_column_displacement(&m, h, &|_| w, 0.0, &[h, h / 2.0]).unwrap();
        let linear = -w * h * h / (2.0 * big_m);
        assert!((u[0] - linear).abs() < 1e-3 * linear.abs(), "{} vs {linear}", u[0]);
        // At mid-height: −w (H Z − Z²/2) / M.
        let mid = -w * (h * h / 2.0 - h * h / 8.0) / big_m;
        assert!((u[1] - mid).abs() < 1e-3 * mid.abs());
        // The stretch inverts the stress law.
        let l = confined_stretch(&m, -500.0).unwrap();
        assert!((confined_axial_pk1(&m, l).unwrap() + 500.0).abs() < 1e-9);
        // Weightless, pressed at the top: homogeneous, u = (λ − 1) Z.
        let u = confined_column_displacement(&m, h, &|_| 0.0, -500.0, &[h, h / 2.0]).unwrap();
        assert!((u[0] - (l - 1.0) * h).abs() < 1e-9 && (u[1] - (l - 1.0) * h / 2.0).abs() < 1e-9);
    }

    /// Small strain: l − 1 = −ν(λ − 1) to first order, with ν = (3κ − 2μ)/(2(3κ + μ)).
    #[test]
    fn small_strain_limit_is_poisson() {
        let (mu, kappa) = (1.0, 2.5);
        let nu = (3.0 * kappa - 2.0 * mu) / (2.0 * (3.0 * kappa + mu));
        let eps = 1e-6;
        let l = neo_hookean_uniaxial_lateral_stretch(1.0 - eps, mu, kappa).unwrap();
        assert!(((l - 1.0) / eps - nu).abs() < 1e-5, "{} vs {nu}", (l - 1.0) / eps);
    }

    /// Incompressible limit: J → 1, so l → λ^(−1/2).
    #[test]
    fn nearly_incompressible_keeps_volume() {
        let l = neo_hookean_uniaxial_lateral_stretch(0.8, 1.0, 1e7).unwrap();
        assert!((l * l * 0.8 - 1.0).abs() < 1e-6, "J = {}", l * l * 0.8);
    }

    /// The closed-form P₃₃ is the derivative of each law's energy along F = diag(1, 1, λ)
    /// (central difference of `Material::energy`, an independent path through the code).
    #[test]
    fn confined_stress_is_the_energy_derivative() {
        use nalgebra::Matrix3;
        for m in [
            Material::neo_hookean(3000.0, 0.49).unwrap(),
            Material::st_venant_kirchhoff(300.0, 0.1).unwrap(),
        ] {
            for lambda in [0.7, 0.93, 1.0, 1.2] {
                let w = |s: f64| m.energy(&Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, s));
                let h = 1e-5;
                let fd = (w(lambda + h).unwrap() - w(lambda - h).unwrap()) / (2.0 * h);
                let p = confined_axial_pk1(&m, lambda).unwrap();
                let scale = m.elastic().p_wave_modulus();
                assert!((p - fd).abs() <= 1e-7 * scale, "{} at {lambda}: {p} vs {fd}", m.name());
            }
        }
    }

    /// Two equal materials in series stretch alike: λ₁ = λ₂ = 1 − d/L. A stiffer second bar
    /// takes less of the shortening, and the stresses balance.
    #[test]
    fn series_split_balances_the_stresses() {
        let a = Material::neo_hookean(3000.0, 0.3).unwrap();
        let [s1, s2] = confined_series_stretches((&a, 0.6), (&a, 0.4), 0.1).unwrap();
        assert!((s1 - 0.9).abs() < 1e-14 && (s2 - 0.9).abs() < 1e-14, "{s1} {s2}");
        let b = Material::st_venant_kirchhoff(1000.0, 0.2).unwrap();
        let [s1, s2] = confined_series_stretches((&a, 0.6), (&b, 0.4), 0.1).unwrap();
        assert!(s1 > 0.9 && s2 < 0.9, "{s1} {s2}");
        assert!((0.6 * s1 + 0.4 * s2 - 0.9).abs() < 1e-14);
        let (p1, p2) = (confined_axial_pk1(&a, s1).unwrap(), confined_axial_pk1(&b, s2).unwrap());
        assert!((p1 - p2).abs() <= 1e-12 * p1.abs(), "{p1} vs {p2}");
        // No state: a shortening beyond the SVK bar's stable branch.
        assert!(confined_series_stretches((&b, 0.5), (&b, 0.5), 0.5).is_none());
        let o = Material::ogden(3000.0, 0.49, -4.7).unwrap();
        assert!(confined_series_stretches((&a, 0.5), (&o, 0.5), 0.1).is_none());
    }
}
