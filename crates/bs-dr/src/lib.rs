//! Total Lagrangian explicit dynamics (TLED) element kernels and three steady-state solvers
//! behind one trait: the semismooth Newton–Krylov solver (the default: a multilevel
//! preconditioner following the state, kinematic contact linearised on its active set), the paper's adaptive
//! Dynamic Relaxation, and a static Newton–Raphson reference with a direct factorisation.
//!
//! Architecture invariant: this crate knows elements, materials and nodal vectors. It knows
//! nothing of contact geometry (buckets, triangles, closest points): the contact reaches the
//! solver only through the small [`Contact`] trait owned here, called after every step. It
//! must not depend on `bs-contact`; `bs-scene` composes the two.
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
//! let sol = dr.solve(&model, &loads, &mut NoContact, &mut |_p| {})?;
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
//! Layers, lowest first (each folder imports only the rows above it; `cargo xtask deps`
//! checks it): [`element`] (one element's data), `kernels` (TLED forces on SIMD lanes),
//! [`linalg`] (nodal vectors, sparse matrices, GMRES, the multilevel preconditioner),
//! [`assembly`] (internal forces, `K₀`, element tangents), [`model`] and `mass` (the
//! model, its masses and time steps), then the solvers ([`dr`], [`newton`],
//! [`newton_krylov`]) with their seams ([`contact`], [`loads`]), the common [`solver`]
//! types and [`post`]. Each solver has its own parameters, info and error
//! ([`DrParams`]/[`DrInfo`]/[`DrError`], [`NewtonParams`]/[`NewtonInfo`]/[`NewtonError`];
//! Newton–Krylov still reports through the common [`Report`] and [`SolveError`]), and the
//! [`Solver`] trait converts them into the common ones.

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
    NewtonKrylovParams, Preparation, Response, ResponseInfo, WarmStart,
};
pub use post::ElementMeasures;
pub use solver::{
    Breakdown, ContinuationSummary, LoadFailure, Progress, Report, Solution, SolveError, Solver,
    ToleranceUnit, load_scale,
};

#[cfg(test)]
pub(crate) mod tests;
