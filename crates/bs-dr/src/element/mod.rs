//! Element data, the bottom layer of the solver: what one element is, independent of any
//! other. [`Solid`] and [`TetFormulation`] say what it is made of; `Tet` and `Hex` hold the
//! precomputed reference data (volume, shape-function gradients, the H8 hourglass matrix);
//! `kinematics` computes `F` and `det F`; `bound` the largest eigenvalue of an element's
//! small-strain stiffness (critical steps, DR masses); `ElementView` is one element for the
//! loops that treat tetrahedra and hexahedra alike.
//!
//! Architecture invariant: this folder imports no other module of the crate.

pub(crate) mod bound;
pub(crate) mod hex;
pub(crate) mod hourglass;
pub(crate) mod kinematics;
pub(crate) mod solid;
pub(crate) mod step;
pub(crate) mod tet;
pub(crate) mod view;

pub(crate) use hex::Hex;
pub use solid::{Solid, TetFormulation};
pub(crate) use tet::Tet;
pub(crate) use view::ElementView;

#[cfg(test)]
mod tests;
