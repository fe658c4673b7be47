//! Kinematic brain–skull contact against a rigid closed triangle surface.
//!
//! After every solver step each brain-surface (slave) node that has left the skull cavity
//! is moved to the closest point of the skull (master) surface: bucket search for the
//! closest master node, local search over the faces and edges around it plus precomputed
//! per-node lists of additional faces and edges (Joldes et al., brain–skull contact paper,
//! section 3).
//!
//! Architecture invariant: this crate knows triangle surfaces and points. It knows nothing
//! of elements, materials or Dynamic Relaxation, and must not depend on `bs-dr`.
//!
//! The handlers arrive with the contact issue.
