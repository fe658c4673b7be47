//! Linear algebra on nodal vectors (`[Vector3<f64>]`, one entry per mesh node): the
//! deterministic vector kernels and sparse matrices ([`sparse`]), the two-part matrix of
//! `K₀` ([`nodal`]), restarted GMRES, one system or a batch in lockstep ([`krylov`]) and the multilevel preconditioner
//! ([`multilevel`]: parameters, nodal projector, aggregates, products, levels, setup,
//! rebuild and cycle).
//!
//! Architecture invariant: this folder knows matrices, vectors, node coordinates and
//! constraints, never elements or the model; it imports only the SIMD lanes of `kernels`.
//! Every reduction is bit-identical for any thread count.

pub mod krylov;
pub mod multilevel;
pub mod nodal;
pub mod sparse;
