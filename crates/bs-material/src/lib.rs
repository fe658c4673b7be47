//! Hyperelastic constitutive laws for brain tissue.
//!
//! A law maps the deformation gradient `F` to a strain-energy density `W` (per unit reference
//! volume), the second Piola–Kirchhoff stress `S = ∂W/∂E = 2 ∂W/∂C` and, for implicit
//! solvers, the material tangent `ℂ = ∂S/∂E`. Laws are stateless types implementing
//! [`Hyperelastic`] with a separate parameter type (the fenris style); [`Material`] is the
//! run-time choice of a law and its parameters, used by the element kernels.
//!
//! | law | energy density `W` |
//! |-----|--------------------|
//! | [`NeoHookean`] | `μ/2 (Ī₁ − 3) + κ/2 (J − 1)²`, `Ī₁ = J^(−2/3) tr C` (CalculiX `*HYPERELASTIC, NEO HOOKE` with `C10 = μ/2`, `D1 = 2/κ`) |
//! | [`StVenantKirchhoff`] | `λ/2 (tr E)² + μ E:E`, `E = (C − I)/2` |
//! | [`Ogden`] | `2μ/α² (λ̄₁^α + λ̄₂^α + λ̄₃^α − 3) + κ/2 (J − 1)²`, `λ̄ᵢ = J^(−1/3) λᵢ` (one term; initial shear modulus `μ` for every `α`) |
//!
//! Conventions: the tangent is a 6×6 matrix in Voigt order `(11, 22, 33, 23, 13, 12)` acting
//! on the engineering strain vector `(E₁₁, E₂₂, E₃₃, 2E₂₃, 2E₁₃, 2E₁₂)`, so `dS = ℂ dE` and
//! `ℂ` is symmetric. `J = det F ≤ 0` (an inverted material point) is a
//! [`MaterialError::NonPositiveJacobian`], never a NaN.
//!
//! The `*_cj` methods are the unchecked kernels used in hot loops: they take the right
//! Cauchy–Green tensor `C = FᵀF` and `J = det F`, and require `J > 0` and `J² = det C`.
//!
//! Architecture invariant: this crate knows nothing about meshes, elements, solvers or
//! contact. It depends on nalgebra alone (for 3×3 algebra).

use nalgebra::{Matrix3, SMatrix, SymmetricEigen, Vector3};

/// 6×6 material tangent in Voigt notation (see the crate docs for the ordering).
pub type Tangent = SMatrix<f64, 6, 6>;

/// Voigt index pairs in the order `(11, 22, 33, 23, 13, 12)`.
pub const VOIGT: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)];

/// Errors of the constitutive laws.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum MaterialError {
    /// The deformation gradient has `det F ≤ 0` (or a non-finite determinant): the material
    /// point is inverted or collapsed.
    #[error(
        "inverted material point: det F = {j:e} (must be > 0); the element is inverted or \
         collapsed — check the mesh orientation, reduce the load or the time step"
    )]
    NonPositiveJacobian {
        /// The offending `det F`.
        j: f64,
    },
    /// A material parameter is out of its admissible range.
    #[error("invalid material parameter {name} = {value}: {requirement}")]
    InvalidParameter {
        /// Parameter name (`"E"`, `"nu"`, `"mu"`, …).
        name: &'static str,
        /// The value given.
        value: f64,
        /// What the parameter must satisfy.
        requirement: &'static str,
    },
}

fn check(
    name: &'static str,
    value: f64,
    ok: bool,
    requirement: &'static str,
) -> Result<(), MaterialError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(MaterialError::InvalidParameter { name, value, requirement })
    }
}

/// Isotropic small-strain elastic constants, the common currency for parameter conversion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Elastic {
    /// Shear modulus μ (> 0).
    pub mu: f64,
    /// Bulk modulus κ (> 0).
    pub kappa: f64,
}

impl Elastic {
    /// From Young's modulus `E > 0` and Poisson's ratio `ν ∈ (−1, 0.5)`:
    /// `μ = E / (2(1+ν))`, `κ = E / (3(1−2ν))`.
    pub fn from_young_poisson(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        check("E", young, young > 0.0, "Young's modulus must be > 0")?;
        check(
            "nu",
            poisson,
            poisson > -1.0 && poisson < 0.5,
            "Poisson's ratio must lie in (-1, 0.5)",
        )?;
        Ok(Elastic {
            mu: young / (2.0 * (1.0 + poisson)),
            kappa: young / (3.0 * (1.0 - 2.0 * poisson)),
        })
    }

    /// From shear modulus `μ > 0` and bulk modulus `κ > 0`.
    pub fn from_mu_kappa(mu: f64, kappa: f64) -> Result<Self, MaterialError> {
        check("mu", mu, mu > 0.0, "shear modulus must be > 0")?;
        check("kappa", kappa, kappa > 0.0, "bulk modulus must be > 0")?;
        Ok(Elastic { mu, kappa })
    }

    /// Lamé's first parameter `λ = κ − 2μ/3`.
    pub fn lambda(&self) -> f64 {
        self.kappa - 2.0 * self.mu / 3.0
    }

    /// Young's modulus `E = 9κμ / (3κ + μ)`.
    pub fn young(&self) -> f64 {
        9.0 * self.kappa * self.mu / (3.0 * self.kappa + self.mu)
    }

    /// Poisson's ratio `ν = (3κ − 2μ) / (2(3κ + μ))`.
    pub fn poisson(&self) -> f64 {
        (3.0 * self.kappa - 2.0 * self.mu) / (2.0 * (3.0 * self.kappa + self.mu))
    }

    /// P-wave (dilatational) modulus `λ + 2μ = κ + 4μ/3`; the dilatational wave speed is
    /// `sqrt((λ + 2μ)/ρ)`.
    pub fn p_wave_modulus(&self) -> f64 {
        self.kappa + 4.0 * self.mu / 3.0
    }

    /// The small-strain isotropic elasticity matrix in this crate's Voigt convention.
    pub fn small_strain_tangent(&self) -> Tangent {
        let l = self.lambda();
        let mut d = Tangent::zeros();
        for i in 0..3 {
            for j in 0..3 {
                d[(i, j)] = l;
            }
            d[(i, i)] += 2.0 * self.mu;
            d[(i + 3, i + 3)] = self.mu;
        }
        d
    }
}

/// A hyperelastic law: a stateless type with a parameter type.
///
/// Implementors provide the unchecked `*_cj` kernels; the checked methods taking `F` (or `C`)
/// are provided and return [`MaterialError::NonPositiveJacobian`] for `J ≤ 0`.
pub trait Hyperelastic {
    /// The law's parameters.
    type Params: Copy + std::fmt::Debug + Send + Sync;

    /// Strain-energy density from `C` and `J` (requires `J > 0`, `J² = det C`).
    fn energy_cj(p: &Self::Params, c: &Matrix3<f64>, j: f64) -> f64;

    /// Second Piola–Kirchhoff stress from `C` and `J` (requires `J > 0`, `J² = det C`).
    fn pk2_cj(p: &Self::Params, c: &Matrix3<f64>, j: f64) -> Matrix3<f64>;

    /// `S` and the tangent `ℂ = ∂S/∂E` from `C` and `J` (requires `J > 0`, `J² = det C`).
    fn tangent_cj(p: &Self::Params, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent);

    /// First Piola–Kirchhoff stress `P = F S` from `F` and `J = det F > 0` (unchecked). The
    /// default forms `C` and `S`; laws with a cheaper direct form override it.
    #[inline]
    fn pk1_fj(p: &Self::Params, f: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        f * Self::pk2_cj(p, &(f.transpose() * f), j)
    }

    /// Strain-energy density `W(F)`.
    fn energy(p: &Self::Params, f: &Matrix3<f64>) -> Result<f64, MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(Self::energy_cj(p, &c, j))
    }

    /// Second Piola–Kirchhoff stress `S(F)`.
    fn pk2(p: &Self::Params, f: &Matrix3<f64>) -> Result<Matrix3<f64>, MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(Self::pk2_cj(p, &c, j))
    }

    /// `S(F)` and the tangent `ℂ = ∂S/∂E`.
    fn tangent(
        p: &Self::Params,
        f: &Matrix3<f64>,
    ) -> Result<(Matrix3<f64>, Tangent), MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(Self::tangent_cj(p, &c, j))
    }

    /// Strain-energy density as a function of a symmetric, positive-definite `C` alone
    /// (`J = sqrt(det C)`; orientation cannot be checked from `C`).
    fn energy_c(p: &Self::Params, c: &Matrix3<f64>) -> Result<f64, MaterialError> {
        let j = jacobian_from_c(c)?;
        Ok(Self::energy_cj(p, c, j))
    }

    /// `S` as a function of `C` alone, see [`Hyperelastic::energy_c`].
    fn pk2_c(p: &Self::Params, c: &Matrix3<f64>) -> Result<Matrix3<f64>, MaterialError> {
        let j = jacobian_from_c(c)?;
        Ok(Self::pk2_cj(p, c, j))
    }
}

/// `x^(−1/3)` for finite `x > 0`, to within a few ulp, without calling libm.
///
/// The hot stress kernels need `J^(−2/3) = (J²)^(−1/3)` once per element per step; the libm
/// `cbrt` the toolchain links was a quarter of the T4 kernel time. Exponent-division bit
/// guess (magic constant tuned for ≤ 3.5% error), then two steps of the cubically convergent
/// iteration `r ← r (1 + ε/3 + 2ε²/9)`, `ε = 1 − x r³` (3.5e-2 → 7e-6 → round-off), and one
/// Newton step to settle round-off (worst relative error measured against 40-digit decimal
/// arithmetic over 1e-20..1e20: 1.6e-16). Falls back to `powf` outside `[1e-300, 1e300]`.
#[inline]
pub fn inv_cbrt(x: f64) -> f64 {
    if !(1e-300..=1e300).contains(&x) {
        return x.powf(-1.0 / 3.0);
    }
    let mut r = f64::from_bits(0x553e_f100_0000_0000 - x.to_bits() / 3);
    for _ in 0..2 {
        let e = 1.0 - x * r * r * r;
        r *= 1.0 + e * (1.0 / 3.0 + e * (2.0 / 9.0));
    }
    let e = 1.0 - x * r * r * r;
    r + r * e * (1.0 / 3.0)
}

/// `C = FᵀF` and `J = det F`, or an error for `J ≤ 0` / non-finite `J`.
pub fn kinematics(f: &Matrix3<f64>) -> Result<(Matrix3<f64>, f64), MaterialError> {
    let j = f.determinant();
    if !(j > 0.0 && j.is_finite()) {
        return Err(MaterialError::NonPositiveJacobian { j });
    }
    Ok((f.transpose() * f, j))
}

fn jacobian_from_c(c: &Matrix3<f64>) -> Result<f64, MaterialError> {
    let d = c.determinant();
    if !(d > 0.0 && d.is_finite()) {
        return Err(MaterialError::NonPositiveJacobian { j: d.abs().sqrt().copysign(d) });
    }
    Ok(d.sqrt())
}

/// Inverse of a symmetric 3×3 matrix with known determinant (cofactor formula).
#[inline]
fn sym_inverse(c: &Matrix3<f64>, det: f64) -> Matrix3<f64> {
    let inv = 1.0 / det;
    let a00 = (c[(1, 1)] * c[(2, 2)] - c[(1, 2)] * c[(2, 1)]) * inv;
    let a01 = (c[(0, 2)] * c[(2, 1)] - c[(0, 1)] * c[(2, 2)]) * inv;
    let a02 = (c[(0, 1)] * c[(1, 2)] - c[(0, 2)] * c[(1, 1)]) * inv;
    let a11 = (c[(0, 0)] * c[(2, 2)] - c[(0, 2)] * c[(2, 0)]) * inv;
    let a12 = (c[(0, 2)] * c[(1, 0)] - c[(0, 0)] * c[(1, 2)]) * inv;
    let a22 = (c[(0, 0)] * c[(1, 1)] - c[(0, 1)] * c[(1, 0)]) * inv;
    Matrix3::new(a00, a01, a02, a01, a11, a12, a02, a12, a22)
}

/// Voigt tangent of `A ⊙ B` style products: `out += s · (a ⊗ b)` in Voigt form, where `a`
/// and `b` are symmetric tensors (outer product of their Voigt vectors, no shear factor).
#[inline]
fn add_outer(d: &mut Tangent, s: f64, a: &Matrix3<f64>, b: &Matrix3<f64>) {
    for (r, &(i, j)) in VOIGT.iter().enumerate() {
        for (q, &(k, l)) in VOIGT.iter().enumerate() {
            d[(r, q)] += s * a[(i, j)] * b[(k, l)];
        }
    }
}

/// Voigt form of the fourth-order tensor `s · ∂(A⁻¹)/∂A`-type term
/// `−s · ½ (A_ik A_jl + A_il A_jk)` for symmetric `A` (as it acts on engineering strain).
#[inline]
fn add_sym_product(d: &mut Tangent, s: f64, a: &Matrix3<f64>) {
    for (r, &(i, j)) in VOIGT.iter().enumerate() {
        for (q, &(k, l)) in VOIGT.iter().enumerate() {
            d[(r, q)] += s * 0.5 * (a[(i, k)] * a[(j, l)] + a[(i, l)] * a[(j, k)]);
        }
    }
}

/// Decoupled compressible Neo-Hookean law
/// `W = μ/2 (J^(−2/3) tr C − 3) + κ/2 (J − 1)²`.
///
/// `S = μ J^(−2/3) (I − (tr C / 3) C⁻¹) + κ J (J − 1) C⁻¹`. Parameters: [`Elastic`].
#[derive(Debug, Clone, Copy, Default)]
pub struct NeoHookean;

impl Hyperelastic for NeoHookean {
    type Params = Elastic;

    fn energy_cj(p: &Elastic, c: &Matrix3<f64>, j: f64) -> f64 {
        let i1 = c.trace();
        0.5 * p.mu * (i1 * j.powf(-2.0 / 3.0) - 3.0) + 0.5 * p.kappa * (j - 1.0) * (j - 1.0)
    }

    #[inline]
    fn pk2_cj(p: &Elastic, c: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        let cinv = sym_inverse(c, j * j);
        let a = p.mu * inv_cbrt(j * j);
        let i1 = c.trace();
        let b = p.kappa * j * (j - 1.0) - a * i1 / 3.0;
        let mut s = cinv * b;
        s[(0, 0)] += a;
        s[(1, 1)] += a;
        s[(2, 2)] += a;
        s
    }

    /// `P = μ J^(−2/3) (F − (I₁/3) F⁻ᵀ) + κ J (J − 1) F⁻ᵀ` with `F⁻ᵀ = cof(F)/J`, `I₁ = F:F`:
    /// no `C`, no inverse of `C`, no product `F S`.
    #[inline]
    fn pk1_fj(p: &Elastic, f: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        let cof = Matrix3::new(
            f[(1, 1)] * f[(2, 2)] - f[(1, 2)] * f[(2, 1)],
            f[(1, 2)] * f[(2, 0)] - f[(1, 0)] * f[(2, 2)],
            f[(1, 0)] * f[(2, 1)] - f[(1, 1)] * f[(2, 0)],
            f[(0, 2)] * f[(2, 1)] - f[(0, 1)] * f[(2, 2)],
            f[(0, 0)] * f[(2, 2)] - f[(0, 2)] * f[(2, 0)],
            f[(0, 1)] * f[(2, 0)] - f[(0, 0)] * f[(2, 1)],
            f[(0, 1)] * f[(1, 2)] - f[(0, 2)] * f[(1, 1)],
            f[(0, 2)] * f[(1, 0)] - f[(0, 0)] * f[(1, 2)],
            f[(0, 0)] * f[(1, 1)] - f[(0, 1)] * f[(1, 0)],
        );
        let r = inv_cbrt(j * j); // J^(−2/3); r³ = J⁻², so 1/J = J r³ (no division)
        let a = p.mu * r;
        let i1 = f.norm_squared();
        // coefficient of F⁻ᵀ = cof/J
        let b = (p.kappa * j * (j - 1.0) - a * i1 * (1.0 / 3.0)) * (j * r * r * r);
        f * a + cof * b
    }

    fn tangent_cj(p: &Elastic, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent) {
        // S = a (I − I₁/3 C⁻¹) + g C⁻¹ with a = μ J^(−2/3), g = κ J (J−1).
        // dJ/dE = J C⁻¹, dC⁻¹/dE = −(C⁻¹ ⊙ C⁻¹) (symmetrised product, times 2 for E vs C/2),
        // dI₁/dE = 2 I, da/dE = −(2/3) a C⁻¹.
        let cinv = sym_inverse(c, j * j);
        let a = p.mu / (j * j).cbrt();
        let i1 = c.trace();
        let g = p.kappa * j * (j - 1.0);
        let dg_dj = p.kappa * (2.0 * j - 1.0);
        let id = Matrix3::identity();
        let s = (id - cinv * (i1 / 3.0)) * a + cinv * g;
        let mut d = Tangent::zeros();
        // d[a (I − I₁/3 C⁻¹)]: da ⊗ (I − I₁/3 C⁻¹) = −(2/3) a (I − I₁/3 C⁻¹) ⊗ C⁻¹
        add_outer(&mut d, -2.0 / 3.0 * a, &(id - cinv * (i1 / 3.0)), &cinv);
        // −a/3 C⁻¹ ⊗ dI₁ = −(2a/3) C⁻¹ ⊗ I
        add_outer(&mut d, -2.0 / 3.0 * a, &cinv, &id);
        // −a I₁/3 dC⁻¹ = +2 a I₁/3 (C⁻¹ ⊙ C⁻¹)
        add_sym_product(&mut d, 2.0 * a * i1 / 3.0, &cinv);
        // d[g C⁻¹] = g'(J) J C⁻¹ ⊗ C⁻¹ − 2 g (C⁻¹ ⊙ C⁻¹)
        add_outer(&mut d, dg_dj * j, &cinv, &cinv);
        add_sym_product(&mut d, -2.0 * g, &cinv);
        (s, d)
    }
}

/// Parameters of the St Venant–Kirchhoff law (Lamé constants).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lame {
    /// Lamé's first parameter λ.
    pub lambda: f64,
    /// Shear modulus μ.
    pub mu: f64,
}

impl From<Elastic> for Lame {
    fn from(e: Elastic) -> Self {
        Lame { lambda: e.lambda(), mu: e.mu }
    }
}

/// St Venant–Kirchhoff law `W = λ/2 (tr E)² + μ E:E`, `S = λ tr(E) I + 2μ E`: linear
/// elasticity in the Total Lagrangian setting (the "linear elastic" ventricle region).
/// It is not polyconvex and softens in strong compression; `J ≤ 0` is still rejected.
#[derive(Debug, Clone, Copy, Default)]
pub struct StVenantKirchhoff;

impl Hyperelastic for StVenantKirchhoff {
    type Params = Lame;

    fn energy_cj(p: &Lame, c: &Matrix3<f64>, _j: f64) -> f64 {
        let e = (c - Matrix3::identity()) * 0.5;
        let tr = e.trace();
        0.5 * p.lambda * tr * tr + p.mu * e.component_mul(&e).sum()
    }

    #[inline]
    fn pk2_cj(p: &Lame, c: &Matrix3<f64>, _j: f64) -> Matrix3<f64> {
        let e = (c - Matrix3::identity()) * 0.5;
        let tr = e.trace();
        let mut s = e * (2.0 * p.mu);
        for i in 0..3 {
            s[(i, i)] += p.lambda * tr;
        }
        s
    }

    fn tangent_cj(p: &Lame, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent) {
        let s = Self::pk2_cj(p, c, j);
        let d = Elastic { mu: p.mu, kappa: p.lambda + 2.0 * p.mu / 3.0 }.small_strain_tangent();
        (s, d)
    }
}

/// Parameters of the one-term Ogden law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OgdenParams {
    /// Initial shear modulus μ (> 0).
    pub mu: f64,
    /// Exponent α (≠ 0; brain tissue: −4.7).
    pub alpha: f64,
    /// Bulk modulus κ (> 0).
    pub kappa: f64,
}

impl OgdenParams {
    /// Validated parameters.
    pub fn new(mu: f64, alpha: f64, kappa: f64) -> Result<Self, MaterialError> {
        check("mu", mu, mu > 0.0, "shear modulus must be > 0")?;
        check("alpha", alpha, alpha != 0.0, "Ogden exponent must be non-zero")?;
        check("kappa", kappa, kappa > 0.0, "bulk modulus must be > 0")?;
        Ok(OgdenParams { mu, alpha, kappa })
    }

    /// From initial shear modulus, exponent and Poisson's ratio (κ from μ and ν).
    pub fn from_mu_alpha_poisson(mu: f64, alpha: f64, poisson: f64) -> Result<Self, MaterialError> {
        check(
            "nu",
            poisson,
            poisson > -1.0 && poisson < 0.5,
            "Poisson's ratio must lie in (-1, 0.5)",
        )?;
        let kappa = 2.0 * mu * (1.0 + poisson) / (3.0 * (1.0 - 2.0 * poisson));
        Self::new(mu, alpha, kappa)
    }

    /// Brain-tissue parameters of the literature (Miller & Chinzei): μ = 842 Pa, α = −4.7,
    /// with the given Poisson's ratio.
    pub fn brain(poisson: f64) -> Result<Self, MaterialError> {
        Self::from_mu_alpha_poisson(842.0, -4.7, poisson)
    }

    /// Small-strain constants (μ, κ).
    pub fn elastic(&self) -> Elastic {
        Elastic { mu: self.mu, kappa: self.kappa }
    }
}

/// One-term Ogden law, decoupled:
/// `W = 2μ/α² (λ̄₁^α + λ̄₂^α + λ̄₃^α − 3) + κ/2 (J − 1)²` with `λ̄ᵢ = J^(−1/3) λᵢ` and `λᵢ` the
/// principal stretches. Written in the eigenvalues `cᵢ = λᵢ²` of `C`:
/// `W = 2μ/α² (J^(−α/3) Σ cᵢ^(α/2) − 3) + κ/2 (J−1)²`; stress and tangent by the spectral
/// formulas for isotropic functions of `C` (with the coalescent-eigenvalue limit).
#[derive(Debug, Clone, Copy, Default)]
pub struct Ogden;

impl Ogden {
    /// `S_a = 2 ∂W/∂c_a` and `H_ab = ∂S_a/∂c_b` for eigenvalues `c` of C.
    fn principal(
        p: &OgdenParams,
        c: &Vector3<f64>,
        j: f64,
    ) -> (Vector3<f64>, nalgebra::Matrix3<f64>) {
        let al = p.alpha;
        let k = 2.0 * p.mu / (al * al);
        let jm = j.powf(-al / 3.0);
        let pw = c.map(|x| x.powf(al / 2.0)); // c_a^(α/2)
        let sum: f64 = pw.sum();
        // ∂J/∂c_a = J / (2 c_a); ∂(J^(−α/3))/∂c_a = −α/3 J^(−α/3) / (2 c_a)
        // W_iso = k (jm Σ − 3)
        // ∂W_iso/∂c_a = k jm (α/2 pw_a / c_a − α/6 Σ / c_a) = k jm α/2 (pw_a − Σ/3)/c_a
        // W_vol' = κ (J−1) J/(2 c_a)
        let mut sa = Vector3::zeros();
        for a in 0..3 {
            let dw = k * jm * al * 0.5 * (pw[a] - sum / 3.0) / c[a]
                + p.kappa * (j - 1.0) * j / (2.0 * c[a]);
            sa[a] = 2.0 * dw;
        }
        // H_ab = ∂S_a/∂c_b.
        // S_a = k jm α (pw_a − Σ/3)/c_a + κ (J² − J)/c_a
        // ∂jm/∂c_b = −α/6 jm / c_b; ∂pw_a/∂c_b = δ_ab α/2 pw_a / c_a; ∂Σ/∂c_b = α/2 pw_b / c_b
        // ∂(J²−J)/∂c_b = (2J² − J)/(2 c_b)
        let mut h = nalgebra::Matrix3::zeros();
        for a in 0..3 {
            for b in 0..3 {
                let dab = if a == b { 1.0 } else { 0.0 };
                let t = pw[a] - sum / 3.0;
                let dt = dab * al * 0.5 * pw[a] / c[a] - al / 6.0 * pw[b] / c[b];
                let iso = k
                    * al
                    * (-al / 6.0 * jm / c[b] * t / c[a] + jm * dt / c[a]
                        - dab * jm * t / (c[a] * c[a]));
                let vol = p.kappa
                    * ((2.0 * j * j - j) / (2.0 * c[b]) / c[a] - dab * (j * j - j) / (c[a] * c[a]));
                h[(a, b)] = iso + vol;
            }
        }
        (sa, h)
    }
}

impl Hyperelastic for Ogden {
    type Params = OgdenParams;

    fn energy_cj(p: &OgdenParams, c: &Matrix3<f64>, j: f64) -> f64 {
        let eig = SymmetricEigen::new(*c);
        let al = p.alpha;
        let sum: f64 = eig.eigenvalues.iter().map(|&x| x.max(0.0).powf(al / 2.0)).sum();
        2.0 * p.mu / (al * al) * (j.powf(-al / 3.0) * sum - 3.0)
            + 0.5 * p.kappa * (j - 1.0) * (j - 1.0)
    }

    fn pk2_cj(p: &OgdenParams, c: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        let eig = SymmetricEigen::new(*c);
        let cv = eig.eigenvalues;
        let (sa, _) = Self::principal(p, &cv, j);
        let n = &eig.eigenvectors;
        let mut s = Matrix3::zeros();
        for a in 0..3 {
            let v = n.column(a);
            s += v * v.transpose() * sa[a];
        }
        s
    }

    fn tangent_cj(p: &OgdenParams, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent) {
        // S = Σ S_a N_a⊗N_a; ∂S/∂C = Σ_ab H_ab N_a N_a N_b N_b
        //   + Σ_{a≠b} (S_a − S_b)/(c_a − c_b) · ½ (N_a⊗N_b⊗N_a⊗N_b + N_a⊗N_b⊗N_b⊗N_a),
        // ℂ = 2 ∂S/∂C. For (nearly) equal c_a, c_b the quotient is replaced by its limit
        // H_aa − H_ab (exact for a symmetric function of the eigenvalues).
        let eig = SymmetricEigen::new(*c);
        let cv = eig.eigenvalues;
        let (sa, h) = Self::principal(p, &cv, j);
        let n = eig.eigenvectors;
        let na: [Vector3<f64>; 3] = [n.column(0).into(), n.column(1).into(), n.column(2).into()];
        let mut s = Matrix3::zeros();
        for a in 0..3 {
            s += na[a] * na[a].transpose() * sa[a];
        }
        let mut d = Tangent::zeros();
        let scale = cv.abs().max();
        for a in 0..3 {
            let ma = na[a] * na[a].transpose();
            for b in 0..3 {
                let mb = na[b] * na[b].transpose();
                add_outer(&mut d, 2.0 * h[(a, b)], &ma, &mb);
                if a != b {
                    let dc = cv[a] - cv[b];
                    let q = if dc.abs() > 1e-6 * scale {
                        (sa[a] - sa[b]) / dc
                    } else {
                        // limit of the divided difference
                        0.5 * ((h[(a, a)] - h[(a, b)]) + (h[(b, b)] - h[(b, a)]))
                    };
                    // 2 · q · ½ (N_a N_b N_a N_b + N_a N_b N_b N_a) in Voigt form
                    for (r, &(i, jj)) in VOIGT.iter().enumerate() {
                        for (qq, &(k, l)) in VOIGT.iter().enumerate() {
                            let t = na[a][i] * na[b][jj] * na[a][k] * na[b][l]
                                + na[a][i] * na[b][jj] * na[b][k] * na[a][l];
                            // symmetrise in (i, j) for the stress index
                            let t2 = na[a][jj] * na[b][i] * na[a][l] * na[b][k]
                                + na[a][jj] * na[b][i] * na[b][l] * na[a][k];
                            d[(r, qq)] += q * 0.5 * (t + t2);
                        }
                    }
                }
            }
        }
        (s, d)
    }
}

/// A law with its parameters, chosen at run time (what a scene file names).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    /// [`NeoHookean`].
    NeoHookean(Elastic),
    /// [`StVenantKirchhoff`].
    StVenantKirchhoff(Lame),
    /// [`Ogden`].
    Ogden(OgdenParams),
}

impl Material {
    /// Neo-Hookean from `(E, ν)`.
    pub fn neo_hookean(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        Ok(Material::NeoHookean(Elastic::from_young_poisson(young, poisson)?))
    }

    /// St Venant–Kirchhoff from `(E, ν)`.
    pub fn st_venant_kirchhoff(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        Ok(Material::StVenantKirchhoff(Elastic::from_young_poisson(young, poisson)?.into()))
    }

    /// Short name (`"neo-hookean"`, `"st-venant-kirchhoff"`, `"ogden"`).
    pub fn name(&self) -> &'static str {
        match self {
            Material::NeoHookean(_) => "neo-hookean",
            Material::StVenantKirchhoff(_) => "st-venant-kirchhoff",
            Material::Ogden(_) => "ogden",
        }
    }

    /// Small-strain constants at `F = I` (for wave speeds and critical time steps).
    pub fn elastic(&self) -> Elastic {
        match self {
            Material::NeoHookean(e) => *e,
            Material::StVenantKirchhoff(l) => {
                Elastic { mu: l.mu, kappa: l.lambda + 2.0 * l.mu / 3.0 }
            }
            Material::Ogden(o) => o.elastic(),
        }
    }

    /// Unchecked energy kernel, see [`Hyperelastic::energy_cj`].
    pub fn energy_cj(&self, c: &Matrix3<f64>, j: f64) -> f64 {
        match self {
            Material::NeoHookean(p) => NeoHookean::energy_cj(p, c, j),
            Material::StVenantKirchhoff(p) => StVenantKirchhoff::energy_cj(p, c, j),
            Material::Ogden(p) => Ogden::energy_cj(p, c, j),
        }
    }

    /// Unchecked stress kernel, see [`Hyperelastic::pk2_cj`].
    #[inline]
    pub fn pk2_cj(&self, c: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        match self {
            Material::NeoHookean(p) => NeoHookean::pk2_cj(p, c, j),
            Material::StVenantKirchhoff(p) => StVenantKirchhoff::pk2_cj(p, c, j),
            Material::Ogden(p) => Ogden::pk2_cj(p, c, j),
        }
    }

    /// Unchecked first Piola–Kirchhoff kernel, see [`Hyperelastic::pk1_fj`].
    #[inline]
    pub fn pk1_fj(&self, f: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        match self {
            Material::NeoHookean(p) => NeoHookean::pk1_fj(p, f, j),
            Material::StVenantKirchhoff(p) => StVenantKirchhoff::pk1_fj(p, f, j),
            Material::Ogden(p) => Ogden::pk1_fj(p, f, j),
        }
    }

    /// Unchecked tangent kernel, see [`Hyperelastic::tangent_cj`].
    pub fn tangent_cj(&self, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent) {
        match self {
            Material::NeoHookean(p) => NeoHookean::tangent_cj(p, c, j),
            Material::StVenantKirchhoff(p) => StVenantKirchhoff::tangent_cj(p, c, j),
            Material::Ogden(p) => Ogden::tangent_cj(p, c, j),
        }
    }

    /// Checked energy `W(F)`.
    pub fn energy(&self, f: &Matrix3<f64>) -> Result<f64, MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(self.energy_cj(&c, j))
    }

    /// Checked stress `S(F)`.
    pub fn pk2(&self, f: &Matrix3<f64>) -> Result<Matrix3<f64>, MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(self.pk2_cj(&c, j))
    }

    /// Checked `S(F)` and tangent.
    pub fn tangent(&self, f: &Matrix3<f64>) -> Result<(Matrix3<f64>, Tangent), MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(self.tangent_cj(&c, j))
    }
}

pub mod closed_form;

#[cfg(test)]
mod tests;
