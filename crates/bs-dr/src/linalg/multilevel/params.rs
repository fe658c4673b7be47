//! The parameters of the multilevel preconditioner and why it can fail to build.

/// Parameters of the multilevel preconditioner (`Multilevel`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultilevelParams {
    /// Size of the mesh's aggregates (the cells of the first coarse level) in mean edge
    /// lengths of the mesh. Default 4.2.
    pub aggregate_size: f64,
    /// How much coarser each level's aggregation grid is than the one above. Default 3.
    pub coarsening: f64,
    /// A coarse level with at most this many unknowns is solved exactly (a sparse Cholesky
    /// factor) instead of being coarsened again. Default 2000.
    pub coarsest: usize,
    /// Levels at most, the mesh included: 2 is the two-level method (the first coarse level
    /// solved exactly, whatever its size). Default 8.
    pub max_levels: usize,
    /// Degree of the mesh level's Chebyshev smoother (sweeps before and after the coarse
    /// correction). Default 3.
    pub degree: usize,
    /// Degree of the coarse levels' Chebyshev smoother. Their operators are small next to
    /// the mesh's (on the 852k-tet brain level 1 moves a seventh of the mesh level's bytes
    /// per product): measured there, 6 took 14 Newton / 159 GMRES iterations where 3 took
    /// 18 / 193, for 7 % more bytes per cycle. Default 6.
    pub coarse_degree: usize,
    /// Lower end of the smoothed interval as a fraction of `λ_max(D⁻¹A)`. Default 0.1.
    pub lower: f64,
    /// Keep the stiffness after the setup, so that a solve can rebuild the coarse levels
    /// for its contact constraints (`Multilevel::constrain_coarse`); not kept for a split
    /// (the mixed form's block keeps the setup's coarse levels). bs-scene sets it for every
    /// solve: fewer GMRES iterations once nodes are held on the skull (the MNI152 demo's
    /// cold solve 78 → 51). Default false.
    pub contact_coarse: bool,
    /// Solve in the mixed form of `split` when a T4ANP nodal volumetric term is stiffer
    /// than this many times the shear stiffness around it (`κ̄/μ̄`; ν = 0.49 gives 50, 0.499
    /// gives 500). Default 100; infinity never splits.
    pub split_above: f64,
}

impl Default for MultilevelParams {
    fn default() -> Self {
        MultilevelParams {
            aggregate_size: 4.2,
            coarsening: 3.0,
            coarsest: 2000,
            max_levels: 8,
            degree: 3,
            coarse_degree: 6,
            lower: 0.1,
            contact_coarse: false,
            split_above: 100.0,
        }
    }
}

/// Why the preconditioner could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MultilevelError {
    /// The coarsest matrix is not positive definite: the model has a rigid-body mode that no
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
