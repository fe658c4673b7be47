//! The parameters of [`NewtonKrylov`](super::NewtonKrylov): the Newton iteration's, and those
//! of its two named parts that a user may want to tune, the load continuation and the line
//! search.

use crate::linalg::multilevel::MultilevelParams;
use crate::solver::{InvalidParam, ToleranceUnit, param};

/// How the prescribed displacements are applied: in increments of the load fraction λ
/// (0 = the start state's prescribed values, 1 = the final ones).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContinuationParams {
    /// The first increment. Default 1: the whole load at once, which easy loads take; a
    /// step that would crush an element shrinks it at once (see the line search).
    pub initial_increment: f64,
    /// Factor by which the next increment grows after a load level converged in at most
    /// `easy_iterations` iterations (and shrinks after more than `hard_iterations`).
    /// Default 2.
    pub growth: f64,
    /// Default 6.
    pub easy_iterations: usize,
    /// Default 15.
    pub hard_iterations: usize,
    /// Factor applied to the increment when a load level fails (FEBio and Abaqus cut to
    /// 25–50 %). Default 0.25.
    pub cutback: f64,
    /// Failed attempts allowed at one load level before the fallback. Default 5.
    pub max_cutbacks: usize,
    /// Newton iterations allowed at one load level after its last load step before it counts
    /// as failed. Also the share of the solve's budget kept for the end: with this many
    /// iterations left, a level still loading stops at the load it has applied and is
    /// equilibrated there, so that a budget spent while loading ends at a converged fraction
    /// of the load (and the fallback starts from it). Default 30.
    pub level_iterations: usize,
    /// Iterations without a 1 % decrease of the best residual at a level after which it
    /// counts as failed (stalled). Default 8.
    pub stall_iterations: usize,
    /// Tolerance of the intermediate load levels as a multiple of the final one (they only
    /// have to be good starting points). Default 10.
    pub intermediate_tolerance: f64,
    /// Equilibrium iterations at most between two load steps of a level (fewer when the
    /// residual a load step left has fallen tenfold). Default 3.
    pub equilibrium_iterations: usize,
    /// After `max_cutbacks` failed attempts at one level: Dynamic Relaxation from the last
    /// converged state to the full load, before giving up. Default true.
    pub fallback: bool,
}

impl Default for ContinuationParams {
    fn default() -> Self {
        ContinuationParams {
            initial_increment: 1.0,
            growth: 2.0,
            easy_iterations: 6,
            hard_iterations: 15,
            cutback: 0.25,
            max_cutbacks: 5,
            level_iterations: 30,
            stall_iterations: 8,
            intermediate_tolerance: 10.0,
            equilibrium_iterations: 3,
            fallback: true,
        }
    }
}

/// The line search on the natural residual.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineSearchParams {
    /// Fraction of its current volume ratio `J` below which no element may go in one step:
    /// the first trial step is the largest that keeps every `J ≥ volume_fraction · J_now`
    /// (exact per element). Default 0.5.
    pub volume_fraction: f64,
    /// Sufficient decrease: a trial is accepted if the residual falls to
    /// `(1 − armijo α)` of its value. Default 1e-4.
    pub armijo: f64,
    /// Backtracking halves the step down to this fraction of the first trial. Default 1/16.
    pub min_fraction: f64,
}

impl Default for LineSearchParams {
    fn default() -> Self {
        LineSearchParams { volume_fraction: 0.5, armijo: 1e-4, min_fraction: 1.0 / 16.0 }
    }
}

/// Parameters of [`NewtonKrylov`](super::NewtonKrylov).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonKrylovParams {
    /// Convergence tolerance on the last Newton correction, in
    /// [`NewtonKrylovParams::tolerance_unit`]. Default 1e-6.
    pub tolerance: f64,
    /// What the tolerance is measured in: a fraction of the load scale (the largest
    /// prescribed displacement component, or the bounding-box diagonal if none; the
    /// default) or a length.
    pub tolerance_unit: ToleranceUnit,
    /// Newton iterations allowed in all (over every load level). Default 300.
    pub max_iterations: usize,
    /// GMRES iterations allowed per Newton iteration. Default 200.
    pub max_linear_iterations: usize,
    /// GMRES restart length. Default 40.
    pub restart: usize,
    /// Largest relative residual asked of a linear solve (early iterations). Default 0.1.
    pub forcing_max: f64,
    /// Relative residual asked of a linear solve while the contact active set still changes
    /// in more than 1% of the contact nodes. Default 0.5.
    pub forcing_active_set: f64,
    /// Smallest relative residual asked of a linear solve. Default 1e-2 (a correction then
    /// carries an error of about 1% of itself, far below the tolerance near convergence).
    pub forcing_min: f64,
    /// Divergence bound on `max|u|` as a multiple of the load scale. Default 100.
    pub divergence_factor: f64,
    /// The load continuation.
    pub continuation: ContinuationParams,
    /// The line search.
    pub line_search: LineSearchParams,
    /// The preconditioner's parameters.
    pub preconditioner: MultilevelParams,
    /// Rebuild the preconditioner on the current configuration before a linear solve once
    /// the elements have deformed this much since it was built (the volume-weighted root
    /// mean square of `‖ΔF‖`, `Model::strain_change`; see `nk::refresh`); infinity never
    /// rebuilds. Default 0.1.
    pub rebuild_strain: f64,
}

impl Default for NewtonKrylovParams {
    fn default() -> Self {
        NewtonKrylovParams {
            tolerance: 1e-6,
            tolerance_unit: ToleranceUnit::LoadScale,
            max_iterations: 300,
            max_linear_iterations: 200,
            restart: 40,
            forcing_max: 0.1,
            forcing_active_set: 0.5,
            forcing_min: 1e-2,
            divergence_factor: 100.0,
            continuation: ContinuationParams::default(),
            line_search: LineSearchParams::default(),
            preconditioner: MultilevelParams::default(),
            rebuild_strain: 0.1,
        }
    }
}

fn open_unit(name: &'static str, v: f64) -> Result<(), InvalidParam> {
    param(name, v, v > 0.0 && v < 1.0, "must lie in (0, 1)")
}

fn at_least_one(name: &'static str, v: usize) -> Result<(), InvalidParam> {
    param(name, v as f64, v >= 1, "must be >= 1")
}

impl NewtonKrylovParams {
    /// Checks every parameter's range.
    pub(crate) fn validate(&self) -> Result<(), InvalidParam> {
        param("tolerance", self.tolerance, self.tolerance > 0.0, "must be > 0")?;
        at_least_one("max_iterations", self.max_iterations)?;
        at_least_one("max_linear_iterations", self.max_linear_iterations)?;
        at_least_one("restart", self.restart)?;
        open_unit("forcing_max", self.forcing_max)?;
        open_unit("forcing_active_set", self.forcing_active_set)?;
        param(
            "forcing_min",
            self.forcing_min,
            self.forcing_min > 0.0 && self.forcing_min <= self.forcing_max,
            "must lie in (0, forcing_max]",
        )?;
        param(
            "divergence_factor",
            self.divergence_factor,
            self.divergence_factor > 1.0,
            "must be > 1",
        )?;
        let c = &self.continuation;
        param(
            "continuation.initial_increment",
            c.initial_increment,
            c.initial_increment > 0.0 && c.initial_increment <= 1.0,
            "must lie in (0, 1]",
        )?;
        param("continuation.growth", c.growth, c.growth >= 1.0, "must be >= 1")?;
        open_unit("continuation.cutback", c.cutback)?;
        at_least_one("continuation.level_iterations", c.level_iterations)?;
        at_least_one("continuation.stall_iterations", c.stall_iterations)?;
        param(
            "continuation.intermediate_tolerance",
            c.intermediate_tolerance,
            c.intermediate_tolerance >= 1.0,
            "must be >= 1",
        )?;
        let l = &self.line_search;
        param(
            "line_search.volume_fraction",
            l.volume_fraction,
            (0.0..1.0).contains(&l.volume_fraction),
            "must lie in [0, 1)",
        )?;
        open_unit("line_search.armijo", l.armijo)?;
        param(
            "line_search.min_fraction",
            l.min_fraction,
            l.min_fraction > 0.0 && l.min_fraction <= 1.0,
            "must lie in (0, 1]",
        )?;
        param("rebuild_strain", self.rebuild_strain, self.rebuild_strain > 0.0, "must be > 0")?;
        let t = &self.preconditioner;
        param("aggregate_size", t.aggregate_size, t.aggregate_size > 0.0, "must be > 0")?;
        at_least_one("degree", t.degree)?;
        at_least_one("coarse_degree", t.coarse_degree)?;
        open_unit("lower", t.lower)?;
        Ok(())
    }
}
