//! Total Lagrangian explicit dynamics (TLED) element kernels and the adaptive Dynamic
//! Relaxation solver.
//!
//! Architecture invariant: this crate knows elements, materials and nodal vectors. It knows
//! nothing of contact geometry (buckets, triangles, closest points): the contact reaches the
//! solver only through a small trait owned here, called after every step. It must not depend
//! on `bs-contact`; `bs-cli` composes the two.
//!
//! The kernels and the solver arrive with the solver issue.
