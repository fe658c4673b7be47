//! Property tests shared by every law (one macro) and closed-form checks.
//!
//! Finite-difference tolerances: central differences have truncation error `O(h²)` times the
//! third derivative and round-off `O(ε W / h)`. With `h = 1e-6` (strains are O(0.1–1)),
//! truncation is ~1e-12 relative and round-off ~1e-16 · W / 1e-6 ~ 1e-10 relative to the
//! stress scale; a relative tolerance of 1e-5 of the largest entry (plus the shear modulus as
//! an absolute floor for entries near zero) leaves four orders of margin and still catches any
//! wrong factor or sign (those give O(1) relative errors).

use super::*;
use nalgebra::{Matrix3, Rotation3, SMatrix, Unit, Vector3};
use proptest::prelude::*;

const H: f64 = 1e-6;
const REL: f64 = 1e-5;

fn c_of(f: &Matrix3<f64>) -> Matrix3<f64> {
    f.transpose() * f
}

/// Perturb `C` by the engineering-strain unit vector `q` (Voigt) scaled by `d`.
fn perturb_c(c: &Matrix3<f64>, q: usize, d: f64) -> Matrix3<f64> {
    let (k, l) = VOIGT[q];
    let mut c2 = *c;
    if k == l {
        c2[(k, k)] += 2.0 * d; // E_kk += d
    } else {
        c2[(k, l)] += d; // 2E_kl += d  =>  C_kl += d
        c2[(l, k)] += d;
    }
    c2
}

fn max_abs<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> f64 {
    m.iter().fold(0.0f64, |a, &x| a.max(x.abs()))
}

fn f_from(v: [f64; 9]) -> Matrix3<f64> {
    Matrix3::identity() + Matrix3::from_row_slice(&v)
}

fn rotation(axis: [f64; 3], angle: f64) -> Matrix3<f64> {
    let a = Vector3::from(axis);
    let a = if a.norm() < 1e-3 { Vector3::x() } else { a };
    Rotation3::from_axis_angle(&Unit::new_normalize(a), angle).into_inner()
}

macro_rules! law_properties {
    ($modname:ident, $law:ty, $params:expr, $mu:expr) => {
        mod $modname {
            use super::*;

            fn params() -> <$law as Hyperelastic>::Params {
                $params
            }

            #[test]
            fn zero_stress_and_energy_at_identity() {
                let p = params();
                let id = Matrix3::identity();
                let s = <$law>::pk2(&p, &id).unwrap();
                // Exact in exact arithmetic; 1e-10 μ allows round-off in the eigen solver.
                assert!(max_abs(&s) <= 1e-10 * $mu, "S(I) = {s}");
                let w = <$law>::energy(&p, &id).unwrap();
                assert!(w.abs() <= 1e-10 * $mu, "W(I) = {w}");
            }

            #[test]
            fn inverted_gradient_is_an_error() {
                let p = params();
                let f = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.5));
                assert!(matches!(<$law>::pk2(&p, &f), Err(MaterialError::NonPositiveJacobian { j }) if j == -0.5));
                assert!(matches!(<$law>::energy(&p, &Matrix3::zeros()), Err(MaterialError::NonPositiveJacobian { .. })));
                assert!(<$law>::tangent(&p, &Matrix3::from_element(f64::NAN)).is_err());
            }

            proptest! {
                #![proptest_config(ProptestConfig::with_cases(64))]

                #[test]
                fn stress_is_energy_derivative(v in prop::array::uniform9(-0.35f64..0.35)) {
                    let f = f_from(v);
                    prop_assume!(f.determinant() > 0.3);
                    let p = params();
                    let c = c_of(&f);
                    let s = <$law>::pk2(&p, &f).unwrap();
                    let scale = max_abs(&s) + $mu;
                    for q in 0..6 {
                        let (i, j) = VOIGT[q];
                        let wp = <$law>::energy_c(&p, &perturb_c(&c, q, H)).unwrap();
                        let wm = <$law>::energy_c(&p, &perturb_c(&c, q, -H)).unwrap();
                        // dW = S : dE; for a shear component dE_ij = dE_ji = d/2.
                        let fd = (wp - wm) / (2.0 * H);
                        prop_assert!((fd - s[(i, j)]).abs() <= REL * scale,
                            "S[{i}{j}] = {} but dW/dE = {fd}", s[(i, j)]);
                    }
                }

                #[test]
                fn first_piola_kirchhoff_is_f_times_s(v in prop::array::uniform9(-0.35f64..0.35)) {
                    let f = f_from(v);
                    prop_assume!(f.determinant() > 0.3);
                    let p = params();
                    let s = <$law>::pk2(&p, &f).unwrap();
                    let pk1 = <$law>::pk1_fj(&p, &f, f.determinant());
                    // Different formulas for the same tensor: agree to round-off.
                    prop_assert!(max_abs(&(pk1 - f * s)) <= 1e-12 * (max_abs(&(f * s)) + $mu));
                }

                #[test]
                fn stress_is_symmetric(v in prop::array::uniform9(-0.35f64..0.35)) {
                    let f = f_from(v);
                    prop_assume!(f.determinant() > 0.3);
                    let s = <$law>::pk2(&params(), &f).unwrap();
                    // Symmetric by construction up to round-off.
                    prop_assert!(max_abs(&(s - s.transpose())) <= 1e-12 * (max_abs(&s) + $mu));
                }

                #[test]
                fn objectivity(v in prop::array::uniform9(-0.35f64..0.35),
                               axis in prop::array::uniform3(-1.0f64..1.0),
                               angle in -3.1f64..3.1) {
                    let f = f_from(v);
                    prop_assume!(f.determinant() > 0.3);
                    let p = params();
                    let q = rotation(axis, angle);
                    let w = <$law>::energy(&p, &f).unwrap();
                    let wq = <$law>::energy(&p, &(q * f)).unwrap();
                    let s = <$law>::pk2(&p, &f).unwrap();
                    let sq = <$law>::pk2(&p, &(q * f)).unwrap();
                    // Rotation changes C only by round-off (~1e-16 relative), amplified by at
                    // most the condition of the law: 1e-10 of the scale is generous.
                    prop_assert!((w - wq).abs() <= 1e-10 * (w.abs() + $mu));
                    prop_assert!(max_abs(&(s - sq)) <= 1e-10 * (max_abs(&s) + $mu));
                }

                #[test]
                fn tangent_is_stress_derivative(v in prop::array::uniform9(-0.35f64..0.35)) {
                    let f = f_from(v);
                    prop_assume!(f.determinant() > 0.3);
                    let p = params();
                    let c = c_of(&f);
                    let (s0, d) = <$law>::tangent(&p, &f).unwrap();
                    prop_assert!(max_abs(&(s0 - <$law>::pk2(&p, &f).unwrap())) <= 1e-12 * (max_abs(&s0) + $mu));
                    let scale = max_abs(&d) + $mu;
                    for q in 0..6 {
                        let sp = <$law>::pk2_c(&p, &perturb_c(&c, q, H)).unwrap();
                        let sm = <$law>::pk2_c(&p, &perturb_c(&c, q, -H)).unwrap();
                        let col = (sp - sm) / (2.0 * H);
                        for r in 0..6 {
                            let (i, j) = VOIGT[r];
                            prop_assert!((col[(i, j)] - d[(r, q)]).abs() <= REL * scale,
                                "D[{r},{q}] = {} but dS/dE = {}", d[(r, q)], col[(i, j)]);
                        }
                    }
                    // The tangent of a hyperelastic law is symmetric.
                    prop_assert!(max_abs(&(d - d.transpose())) <= 1e-9 * scale);
                }
            }
        }
    };
}

law_properties!(
    neo_hookean,
    NeoHookean,
    Elastic::from_young_poisson(3000.0, 0.49).unwrap(),
    1006.7
);
law_properties!(
    neo_hookean_compressible,
    NeoHookean,
    Elastic::from_young_poisson(100.0, 0.1).unwrap(),
    45.5
);
law_properties!(
    svk,
    StVenantKirchhoff,
    Elastic::from_young_poisson(100.0, 0.1).unwrap().into(),
    45.5
);
law_properties!(ogden_brain, Ogden, OgdenParams::brain(0.49).unwrap(), 842.0);
law_properties!(ogden_positive, Ogden, OgdenParams::new(500.0, 2.5, 3000.0).unwrap(), 500.0);

/// Every law linearises to isotropic linear elasticity with its (μ, κ) at F = I.
/// Independent expectation: the textbook small-strain matrix built from (E, ν) directly.
#[test]
fn small_strain_limit_is_linear_elasticity() {
    let (e, nu) = (3000.0, 0.45);
    let lam = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let mu = e / (2.0 * (1.0 + nu));
    let mut expected = Tangent::zeros();
    for i in 0..3 {
        for j in 0..3 {
            expected[(i, j)] = lam;
        }
        expected[(i, i)] = lam + 2.0 * mu;
        expected[(i + 3, i + 3)] = mu;
    }
    let el = Elastic::from_young_poisson(e, nu).unwrap();
    let ogden = OgdenParams::new(el.mu, -4.7, el.kappa).unwrap();
    let id = Matrix3::identity();
    for m in
        [Material::NeoHookean(el), Material::StVenantKirchhoff(el.into()), Material::Ogden(ogden)]
    {
        let (_, d) = m.tangent(&id).unwrap();
        // Ogden at F = I uses the coalescent-eigenvalue limit; 1e-8 relative is round-off.
        assert!(max_abs(&(d - expected)) <= 1e-8 * lam, "{}: {d}", m.name());
    }
}

#[test]
fn parameter_conversions() {
    // E = 3000 Pa, ν = 0.49: μ = 3000 / 2.98, κ = 3000 / 0.06 = 50000.
    let el = Elastic::from_young_poisson(3000.0, 0.49).unwrap();
    assert!((el.mu - 3000.0 / 2.98).abs() < 1e-9);
    assert!((el.kappa - 50_000.0).abs() < 1e-7);
    assert!((el.young() - 3000.0).abs() < 1e-9);
    assert!((el.poisson() - 0.49).abs() < 1e-12);
    assert!((el.lambda() - 3000.0 * 0.49 / (1.49 * 0.02)).abs() < 1e-7);
    // CalculiX NEO HOOKE: C10 = μ/2, D1 = 2/κ.
    let c10 = el.mu / 2.0;
    let d1 = 2.0 / el.kappa;
    assert!((c10 - 503.355_704_697_986_6).abs() < 1e-9 && (d1 - 4e-5).abs() < 1e-15);
    // Ogden brain parameters.
    let o = OgdenParams::brain(0.49).unwrap();
    assert_eq!((o.mu, o.alpha), (842.0, -4.7));
    assert!((o.elastic().poisson() - 0.49).abs() < 1e-12);
}

#[test]
fn invalid_parameters_are_typed_errors() {
    for (e, nu, name) in [
        (-1.0, 0.3, "E"),
        (0.0, 0.3, "E"),
        (1.0, 0.5, "nu"),
        (1.0, -1.0, "nu"),
        (f64::NAN, 0.3, "E"),
    ] {
        match Elastic::from_young_poisson(e, nu) {
            Err(MaterialError::InvalidParameter { name: n, .. }) => assert_eq!(n, name),
            other => panic!("expected error for E={e} nu={nu}, got {other:?}"),
        }
    }
    assert!(Elastic::from_mu_kappa(1.0, 0.0).is_err());
    assert!(OgdenParams::new(1.0, 0.0, 1.0).is_err());
    let msg = Elastic::from_young_poisson(1.0, 0.5).unwrap_err().to_string();
    assert!(msg.contains("nu") && msg.contains("(-1, 0.5)"), "{msg}");
}

/// Closed form: Neo-Hookean under pure dilatation F = s I has S = κ J (J−1) C⁻¹ with
/// J = s³, C⁻¹ = s⁻² I (the isochoric part vanishes).
#[test]
fn neo_hookean_pure_dilatation() {
    let el = Elastic::from_mu_kappa(1000.0, 50_000.0).unwrap();
    let s = 1.05f64;
    let j = s * s * s;
    let sig = NeoHookean::pk2(&el, &(Matrix3::identity() * s)).unwrap();
    let expected = el.kappa * j * (j - 1.0) / (s * s);
    assert!(max_abs(&(sig - Matrix3::identity() * expected)) <= 1e-10 * expected);
}

/// Closed form: simple shear F = I + γ e₁⊗e₂ for Neo-Hookean gives (J = 1) the Cauchy shear
/// stress σ₁₂ = μ γ; with S = F⁻¹ σ F⁻ᵀ this is checked through σ = F S Fᵀ.
#[test]
fn neo_hookean_simple_shear_cauchy() {
    let el = Elastic::from_mu_kappa(1000.0, 50_000.0).unwrap();
    for gamma in [0.1, 0.5, 1.0] {
        let mut f = Matrix3::identity();
        f[(0, 1)] = gamma;
        let sigma = f * NeoHookean::pk2(&el, &f).unwrap() * f.transpose();
        assert!((sigma[(0, 1)] - el.mu * gamma).abs() <= 1e-10 * el.mu);
        // σ₁₁ − σ₂₂ = μ γ² (normal-stress difference of the neo-Hookean solid).
        assert!((sigma[(0, 0)] - sigma[(1, 1)] - el.mu * gamma * gamma).abs() <= 1e-10 * el.mu);
    }
}

/// `inv_cbrt` against `powf` over 40 orders of magnitude and near 1. `powf(−1/3)` itself is
/// off by `|ln x| · 1.9e-17` relative because −1/3 is not representable (8.5e-16 at 1e-20),
/// so that comparison allows 4e-16 + that; the exact check is `r³ x = 1` to 1e-15 (three
/// roundings).
#[test]
fn inv_cbrt_is_accurate() {
    let mut x = 1e-20;
    while x < 1e20 {
        for y in [x, x * 1.2345, x * 3.7] {
            let r = inv_cbrt(y);
            let expected = y.powf(-1.0 / 3.0);
            let tol = 4e-16 + y.ln().abs() * 1.9e-17;
            assert!((r - expected).abs() <= tol * expected, "x = {y}: {r} vs {expected}");
            // r³ x = 1 to round-off
            assert!((r * r * r * y - 1.0).abs() <= 1e-15);
        }
        x *= 1.7;
    }
    for j in [0.5, 0.9, 0.999_999, 1.0, 1.000_001, 1.1, 2.0] {
        assert!((inv_cbrt(j * j) - j.powf(-2.0 / 3.0)).abs() <= 4e-16);
    }
    assert_eq!(inv_cbrt(1.0), 1.0);
    assert!(
        (inv_cbrt(1e-310) - 1e-310f64.powf(-1.0 / 3.0)).abs() <= 1e-15 * 1e-310f64.powf(-1.0 / 3.0)
    );
}

/// Relative difference `|a − b| / max(|a|, |b|)` (0 for two zeros).
fn rel(a: f64, b: f64) -> f64 {
    let scale = a.abs().max(b.abs());
    if scale == 0.0 { 0.0 } else { (a - b).abs() / scale }
}

/// Every law built from (E, ν) and from the (μ, κ) of the same (E, ν) is the same law: equal
/// parameters and equal stress and energy at a general `F`, to 1e-12 relative.
#[test]
fn constructors_from_young_poisson_and_mu_kappa_agree() {
    let f = f_from([1.08, 0.03, -0.02, 0.01, 0.93, 0.04, -0.05, 0.02, 1.02]);
    for (young, poisson) in [(3000.0, 0.49), (1.0, 0.0), (210e9, 0.3), (5.0, -0.5), (842.0, 0.4999)]
    {
        let mu = young / (2.0 * (1.0 + poisson));
        let kappa = young / (3.0 * (1.0 - 2.0 * poisson));
        let pairs = [
            (
                Material::neo_hookean(young, poisson).unwrap(),
                Material::neo_hookean_mu_kappa(mu, kappa).unwrap(),
            ),
            (
                Material::st_venant_kirchhoff(young, poisson).unwrap(),
                Material::st_venant_kirchhoff_mu_kappa(mu, kappa).unwrap(),
            ),
            (
                Material::ogden(young, poisson, -4.7).unwrap(),
                Material::ogden_mu_kappa(mu, kappa, -4.7).unwrap(),
            ),
        ];
        for (a, b) in pairs {
            let (ea, eb) = (a.elastic(), b.elastic());
            assert!(rel(ea.mu, eb.mu) <= 1e-12 && rel(ea.kappa, eb.kappa) <= 1e-12, "{a:?} {b:?}");
            assert!(rel(ea.young(), young) <= 1e-12 && rel(eb.young(), young) <= 1e-12);
            let (sa, sb) = (a.pk2(&f).unwrap(), b.pk2(&f).unwrap());
            assert!((sa - sb).amax() <= 1e-12 * sa.amax(), "{}: {sa} vs {sb}", a.name());
            assert!(rel(a.energy(&f).unwrap(), b.energy(&f).unwrap()) <= 1e-12, "{}", a.name());
        }
        // The parameter types agree with the law constructors.
        let lame = Lame::from_young_poisson(young, poisson).unwrap();
        let lame2 = Lame::from_mu_kappa(mu, kappa).unwrap();
        assert!(rel(lame.lambda, lame2.lambda) <= 1e-12 && rel(lame.mu, lame2.mu) <= 1e-12);
        let back = Elastic::from(lame);
        assert!(rel(back.kappa, kappa) <= 1e-12 && back.mu == lame.mu);
        let o = OgdenParams::from_young_poisson(young, poisson, -4.7).unwrap();
        let o2 = OgdenParams::from_mu_kappa(mu, kappa, -4.7).unwrap();
        assert!(rel(o.mu, o2.mu) <= 1e-12 && rel(o.kappa, o2.kappa) <= 1e-12);
    }
}

/// Every constructor names the parameter it rejects, with the same checks.
#[test]
fn every_constructor_names_the_rejected_parameter() {
    let name_of = |r: Result<Material, MaterialError>| match r {
        Err(MaterialError::InvalidParameter { name, .. }) => name,
        other => panic!("expected a parameter error, got {other:?}"),
    };
    for (young, poisson, name) in [(0.0, 0.3, Parameter::Young), (1.0, 0.5, Parameter::Poisson)] {
        assert_eq!(name_of(Material::neo_hookean(young, poisson)), name);
        assert_eq!(name_of(Material::st_venant_kirchhoff(young, poisson)), name);
        assert_eq!(name_of(Material::ogden(young, poisson, 2.0)), name);
    }
    for (mu, kappa, name) in [
        (0.0, 1.0, Parameter::Shear),
        (1.0, -1.0, Parameter::Bulk),
        (f64::NAN, 1.0, Parameter::Shear),
    ] {
        assert_eq!(name_of(Material::neo_hookean_mu_kappa(mu, kappa)), name);
        assert_eq!(name_of(Material::st_venant_kirchhoff_mu_kappa(mu, kappa)), name);
        assert_eq!(name_of(Material::ogden_mu_kappa(mu, kappa, 2.0)), name);
    }
    assert_eq!(name_of(Material::ogden(1.0, 0.3, 0.0)), Parameter::OgdenExponent);
    assert_eq!(name_of(Material::ogden_mu_kappa(1.0, 1.0, 0.0)), Parameter::OgdenExponent);
    let msg = Material::neo_hookean_mu_kappa(1.0, 0.0).unwrap_err().to_string();
    assert!(msg.contains("kappa"), "{msg}");
}
