//! Assembly: element work run over all elements and combined into nodal quantities, with
//! results that do not depend on the thread count.
//!
//! * [`elements`]: the model's elements in assembly order (tets, then hexes), their blocks
//!   and the loops over both;
//! * [`order`]: the tetrahedra's assembly order (a Morton curve through their centroids);
//! * [`runs`]: tet forces summed per run of blocks where they are computed (tet meshes);
//! * [`slots`]: the node → force-slot map (every node sums its slots in a fixed order);
//! * [`forces`]: internal forces through the SIMD kernels, [`gather`]ed per node, with
//!   caller-owned [`workspace`]s; [`inversion`]: which element inverted;
//! * [`scalar`]: the same forces through the scalar reference kernels;
//! * [`stiffness`]: `K₀`, the small-strain stiffness the preconditioner is built from;
//!   [`stiffness_at`]: the same moved in place to the current configuration (the
//!   preconditioner following the state);
//! * [`volumetric`]: the T4ANP nodal volumetric term of `K₀` moved to another configuration
//!   in place (the mixed form's multiplier term);
//! * [`tangent`]: the consistent element tangent of the Newton reference.
//!
//! Architecture invariant: assembly imports the element, kernel and linear-algebra layers;
//! it knows no solver, load or contact.

pub(crate) mod elements;
pub(crate) mod forces;
pub(crate) mod gather;
pub(crate) mod inversion;
pub(crate) mod order;
pub(crate) mod runs;
pub(crate) mod scalar;
pub(crate) mod slots;
pub(crate) mod step_bound;
pub(crate) mod stiffness;
pub(crate) mod stiffness_at;
pub(crate) mod tangent;
pub(crate) mod volumetric;
pub(crate) mod workspace;

pub use inversion::Inversion;
pub use scalar::ReferenceWorkspace;
pub use step_bound::StepBound;
pub use stiffness_at::StiffnessScratch;
pub use volumetric::VolumetricScratch;
pub use workspace::Workspace;
