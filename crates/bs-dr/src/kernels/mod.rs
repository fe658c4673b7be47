//! TLED element kernels: the nodal forces of blocks of four elements (or of one), written to
//! per-element force slots. The assembly layer above runs them over the elements in
//! parallel and gathers the slots into nodal forces.
//!
//! Architecture invariant: the kernels import the element layer only.
//!
//! * [`simd`]: four f64 lanes (AVX2/FMA through `pulp`'s safe token, or a portable
//!   fallback) and the runtime dispatch;
//! * [`layout`]: the blocks of four tets and of four hexes (structure of arrays) derived
//!   from the model's tets and hexes;
//! * [`neo_hookean`]: the Neo-Hookean stress on lanes, mirroring bs-material;
//! * [`tet_block`]: `F` of four tets from the padded displacements, nodal forces, inverted
//!   lanes;
//! * [`t4`], [`t4anp`], [`h8`]: the element kernels;
//! * [`reference`]: the scalar one-element-at-a-time kernels (tests, benchmark baseline,
//!   and the per-element path of laws without a lane-wise form).

pub(crate) mod h8;
pub(crate) mod layout;
pub(crate) mod neo_hookean;
pub(crate) mod reference;
pub mod simd;
pub(crate) mod t4;
pub(crate) mod t4anp;
pub(crate) mod tet_block;

#[cfg(test)]
mod tests;
