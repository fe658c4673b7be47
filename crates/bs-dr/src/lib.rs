//! Total Lagrangian explicit dynamics (TLED) element kernels and three steady-state solvers
//! behind one trait: the semismooth Newton–Krylov solver (the default: a multilevel
//! preconditioner following the state, kinematic contact linearised on its active set), the paper's adaptive
//! Dynamic Relaxation, and a static Newton–Raphson reference with a direct factorisation.
//!
//! Architecture invariant: this crate knows elements, materials and nodal vectors. It knows
//! nothing of contact geometry (buckets, triangles, closest points): the contact reaches the
//! solver only through the small [`Contact`] trait owned here (`enforce` after every DR
//! step; `nodes` and `project` for Newton–Krylov). It must not depend on `bs-contact`;
//! `bs-scene` composes the two. Measurements reach it only through the `DataTerm` seam.
//!
//! # Using it
//!
//! 1. Build a [`Model`] from a [`bs_mesh::Mesh`], a list of [`Solid`]s (law + density) and one
//!    solid index per element, with [`ModelOptions`] choosing the tetrahedron formulation
//!    ([`TetFormulation::T4`] or [`TetFormulation::T4Anp`]; hexahedra are always H8 mean
//!    strain with stiffness hourglass control).
//! 2. Describe the boundary conditions with [`Loads`]: fixed components and prescribed final
//!    displacements per node and component; everything else is traction-free.
//! 3. Pick a [`Solver`]: [`NewtonKrylov`] (any element, kinematic contact through
//!    [`Contact::project`]; [`NewtonKrylov::prepare`] does the load-independent part once),
//!    [`DynamicRelaxation`] (explicit, any element, kinematic contact through
//!    [`Contact::enforce`]) or [`Newton`] (implicit reference; T4 and H8, no contact), and
//!    call [`Solver::solve`] with a [`Contact`] handler ([`NoContact`] if none) and an
//!    observer.
//!
//! ```
//! use bs_dr::bs_material::Material;
//! use bs_dr::bs_mesh::{Element, Mesh, Point3};
//! use bs_dr::{DynamicRelaxation, DrParams, Loads, Model, ModelOptions, NoContact, Solid, Solver};
//!
//! let nodes = vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0),
//!                  Point3::new(0.0, 1.0, 0.0), Point3::new(0.0, 0.0, 1.0)];
//! let mesh = Mesh::new(nodes, vec![Element::tet4([0, 1, 2, 3])]);
//! let solid = Solid { material: Material::neo_hookean(3000.0, 0.45)?, density: 1000.0 };
//! let model = Model::uniform(&mesh, solid, ModelOptions::default())?;
//! let mut loads = Loads::new(model.node_count());
//! for n in 0..3 { loads.fix_node(n)?; }          // base fixed
//! loads.prescribe(3, 2, -0.1)?;                  // apex pushed down by 0.1
//! let dr = DynamicRelaxation::new(DrParams::default());
//! let sol = dr.solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_p| {}))?;
//! assert!((sol.displacements[3].z + 0.1).abs() < 1e-12);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! What the solvers guarantee:
//!
//! * Prescribed components equal their final values exactly in the answer; contact never
//!   moves them (the solver restores them after [`Contact::enforce`]).
//! * DR stops on its error estimate ([`DrParams::tolerance`] × load scale for
//!   [`DrParams::consecutive`] steps), never on a step count; every failure is a typed
//!   [`DrError`] naming the cause and the fix (NaN, inverted element with index and id,
//!   unstable step, unbounded growth, step budget with the error reached).
//! * Internal forces are bit-identical for any rayon thread count; the step loop allocates
//!   nothing (buffers are allocated once per solve).
//! * Newton–Krylov stops when its last correction is below [`NewtonKrylovParams::tolerance`]
//!   × load scale with the prescribed displacement applied and its contact active set
//!   settled; its solves are bit-identical for any thread count (deterministic reductions).
//! * Newton supports T4 and H8 (not T4ANP, not contact) and exists to check the others.
//!
//! Each solver has its own parameters, info and error ([`DrParams`]/[`DrInfo`]/[`DrError`],
//! [`NewtonParams`]/[`NewtonInfo`]/[`NewtonError`], `NewtonKrylovParams`/`NewtonKrylovInfo`/
//! `NewtonKrylovError`), and the [`Solver`] trait converts them into the common [`Report`]
//! and [`SolveError`].
//!
//! # Files
//!
//! Layers, lowest first; each row imports only itself and the rows above it (`cargo xtask
//! deps` checks it):
//!
//! 1. `element/`: one element on its own. `tet.rs` (T4 reference volume and gradients),
//!    `hex.rs` (H8 mean-strain gradients), `hourglass.rs` (the H8 hourglass matrix),
//!    `solid.rs` (`Solid`, `TetFormulation`), `kinematics.rs` (`F` and `det F`), `bound.rs`
//!    (the largest eigenvalue of the small-strain element stiffness), `step.rs` (the largest
//!    step that keeps `det F` above a fraction), `view.rs` (`ElementView`, one element for
//!    loops over tets and hexes alike), `tests.rs`.
//! 2. `kernels/`: TLED forces of blocks of four elements on SIMD lanes. `simd.rs` (the lane
//!    type and runtime AVX2/FMA dispatch), `layout.rs` (the blocked copies of the elements),
//!    `neo_hookean.rs` (the law on lanes), `tet_block.rs` (what T4 and T4ANP share), `t4.rs`,
//!    `t4anp.rs`, `h8.rs`, `reference.rs` (the scalar one-element kernels), `tests.rs`.
//! 3. `linalg/`: nodal vectors and matrices. `sparse.rs` (deterministic dot and norm,
//!    `BlockCsr`, rank-one sums), `nodal.rs` (`NodalMatrix`, the form of `K₀`), `krylov.rs`
//!    (restarted GMRES), `multilevel/` (the smoothed-aggregation preconditioner: `params`,
//!    `projector`, `constraints`, `blocks`, `tentative`, `products`, `operator`, `levels`,
//!    `setup`, `rebuild`, `contact`, `correction`, `cycle`, `split`, `tests`).
//! 4. `assembly/`: element work over all elements. `elements.rs` (assembly order, blocks,
//!    T4ANP groups), `order.rs` (Morton order of the tets), `runs.rs` (tet forces summed per
//!    run of blocks), `slots.rs` (the node → force-slot map), `forces.rs` (the kernels in
//!    parallel), `gather.rs` (each node's slots in a fixed order), `workspace.rs` (the
//!    caller-owned scratch, `Workspace`), `inversion.rs` (the lowest-indexed inverted
//!    element), `scalar.rs` (forces through the scalar kernels), `stiffness.rs` (`K₀`),
//!    `volumetric.rs` (the T4ANP volumetric term moved in place), `stiffness_at.rs` (`K₀`
//!    moved to the current configuration), `tangent.rs` (the consistent element tangent),
//!    `step_bound.rs` (`StepBound` over every element).
//! 5. `model.rs` (`Model`, `ModelOptions`, `ModelError`: the public face of the rows above),
//!    `mass.rs` (lumped and DR masses, critical steps), `body.rs` (`BodyForce`, `Buoyancy`:
//!    consistent nodal loads of a body force).
//! 6. The solvers and their seams. `solver.rs` (the `Solver` trait, `Progress`, `Report`,
//!    `SolveError`, `Solution`), `contact.rs` (the `Contact` trait, `NoContact`), `data.rs`
//!    (the `DataTerm` trait, `Springs`, `NoData`), `loads.rs` (`Loads`: fixed and prescribed
//!    components, dead nodal forces), `post.rs` (`J` and von Mises per element); `dr/`
//!    (`mod.rs` the loop, `params.rs`, `rayleigh.rs`, `guard.rs`, `outcome.rs`); `newton/`
//!    (`mod.rs` the load-step loop, `system.rs` the free-DOF tangent system, `params.rs`,
//!    `outcome.rs`); `nk/` (`mod.rs` preparation, continuation loop and the `Solver` impl,
//!    over `problem.rs`, `iterate.rs`, `continuation.rs`, `loading.rs`, `level.rs`,
//!    `active_set.rs`, `linear.rs`, `mixed.rs`, `forcing.rs`, `refresh.rs`,
//!    `line_search.rs`, `merit.rs`, `termination.rs`, `fallback.rs`, `response.rs`,
//!    `params.rs`, `outcome.rs`).
//!
//! `tests.rs` holds the fixtures shared by the unit tests of several layers.

#![allow(clippy::needless_range_loop)] // index loops mirror the tensor formulas

pub mod assembly;
pub mod body;
pub mod contact;
pub mod data;
pub mod dr;
pub mod element;
mod kernels;
pub mod linalg;
pub mod loads;
mod mass;
pub mod model;
pub mod newton;
pub mod nk;
pub mod post;
pub mod solver;

/// The constitutive laws of [`Solid`], re-exported.
pub use bs_material;
/// The mesh crate of [`Model::new`]'s input, re-exported so that callers need no separate
/// dependency.
pub use bs_mesh;
/// The linear algebra of every nodal vector here.
pub use nalgebra;

#[doc(hidden)]
pub use assembly::ReferenceWorkspace;
pub use assembly::StepBound;
pub use assembly::{Inversion, Workspace};
pub use body::{BodyError, BodyForce, Buoyancy};
pub use contact::{Contact, ContactProjection, ContactReport, NoContact, SurfaceFeature};
pub use data::{DataTerm, NoData, Spring, Springs};
pub use dr::{DrError, DrInfo, DrParams, DynamicRelaxation};
pub use element::{Solid, TetFormulation};
#[doc(hidden)]
pub use kernels::simd::has_avx2_fma;
pub use linalg::multilevel::MultilevelParams;
pub use loads::{LoadError, Loads, ramp};
pub use model::{Model, ModelError, ModelOptions};
pub use newton::{Newton, NewtonError, NewtonInfo, NewtonParams};
pub use nk::{
    ContinuationParams, LineSearchParams, NewtonKrylov, NewtonKrylovError, NewtonKrylovInfo,
    NewtonKrylovParams, Preparation, PreparedNewtonKrylov, Response, ResponseInfo,
};
pub use post::ElementMeasures;
pub use solver::{
    Breakdown, ContinuationSummary, LoadFailure, Problem, Progress, Report, Solution, SolveError,
    Solver, ToleranceUnit, WarmStart, load_scale,
};

#[cfg(test)]
pub(crate) mod tests;
