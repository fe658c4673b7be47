//! The parameters of the two-level preconditioner and why it can fail to build.

/// Parameters of [`TwoLevel`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoLevelParams {
    /// Aggregate (coarse cell) size in mean edge lengths of the mesh. Default 4.2.
    pub aggregate_size: f64,
    /// Degree of the Chebyshev smoother (sweeps before and after the coarse correction).
    /// Default 3.
    pub degree: usize,
    /// Lower end of the smoothed interval as a fraction of `λ_max(D⁻¹K₀)`. Default 0.1.
    pub lower: f64,
    /// Keep `K₀`, the prolongator and `K₀ P` after the setup, so that a solve can rebuild
    /// the coarse matrix for its contact constraints (`TwoLevel::constrain_coarse`); not kept
    /// for a split (the mixed form's block keeps the setup's coarse matrix), nor where the
    /// coarse factor is as dense as `K₀` (a build would cost several GMRES iterations, as on
    /// a 852k-tet brain). bs-scene sets it for every solve: fewer GMRES iterations once
    /// nodes are held on the skull (the MNI152 demo's cold solve 78 → 51) for the memory of
    /// those matrices (about 30 MB there). Default false.
    pub contact_coarse: bool,
    /// Solve in the mixed form of `split` when a T4ANP nodal volumetric term is
    /// stiffer than this many times the shear stiffness around it (`κ̄/μ̄`; ν = 0.49 gives
    /// 50, 0.499 gives 500). Default 100; infinity never splits.
    pub split_above: f64,
}

impl Default for TwoLevelParams {
    fn default() -> Self {
        TwoLevelParams {
            aggregate_size: 4.2,
            degree: 3,
            lower: 0.1,
            contact_coarse: false,
            split_above: 100.0,
        }
    }
}

/// Why the preconditioner could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TwoLevelError {
    /// The coarse matrix is not positive definite: the model has a rigid-body mode that no
    /// fixed component removes.
    #[error(
        "the coarse stiffness is singular: the model can move as a rigid body (fix or prescribe \
         components of at least three non-collinear nodes)"
    )]
    Singular,
    /// The coarse factorisation ran out of memory or indices.
    #[error("the coarse factorisation failed: {0}")]
    Factor(String),
}
