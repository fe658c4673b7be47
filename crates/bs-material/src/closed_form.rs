//! Closed-form homogeneous states of the laws here: independent expectations for the
//! patch tests of the finite-element code (bs-cli's tests, `cargo xtask validate`).

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
