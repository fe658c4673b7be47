//! The caller-owned scratch of the internal forces: padded displacements, the blocked force
//! slots of tets and hexes, the element `J` and the T4ANP nodal averages.

use crate::kernels::h8::HexBlockForces;
use crate::kernels::layout::LANES;
use crate::kernels::tet_block::BlockForces;

use super::elements::Elements;

/// Caller-owned scratch buffers of the internal forces (`Model::internal_forces_into`);
/// allocate once (`Model::workspace`) and reuse every step.
#[derive(Debug, Clone)]
pub struct Workspace {
    /// Displacements padded to `[x, y, z, 0]` (one vector load per node in the kernels).
    pub(super) upad: Vec<[f64; 4]>,
    /// Tet force slots, per block of four tets, tet-major: slot `4t + a` at `3(4t + a)` of
    /// the flattened buffer (see [`BlockForces`]).
    pub(super) tslots: Vec<BlockForces>,
    /// Per run of tet blocks, its nodes' forces (see `runs`; empty without runs).
    pub(super) tacc: Vec<[f64; 4]>,
    /// Hex force slots, per block of four hexes, hex-major: hex slot `8h + a` at
    /// `3(8h + a)` of the flattened buffer (see [`HexBlockForces`]).
    pub(super) hslots: Vec<HexBlockForces>,
    /// Tet `J`, blocked.
    pub(super) tjac: Vec<[f64; LANES]>,
    /// Tet `V J` (T4ANP), blocked.
    pub(super) tvj: Vec<[f64; LANES]>,
    /// Hex `J`, blocked.
    pub(super) hjac: Vec<[f64; LANES]>,
    /// ANP nodal volume ratios.
    pub(super) jnodal: Vec<f64>,
}

impl Elements {
    /// Scratch buffers sized for these elements.
    pub(crate) fn workspace(&self) -> Workspace {
        let nb = self.tet_blocks.len();
        Workspace {
            upad: vec![[0.0; 4]; self.nodes()],
            // One spare block and slot: the gather reads every slot as four values. None
            // when the runs sum the tet forces.
            tslots: vec![[[0.0; LANES]; 12]; if self.runs.is_some() { 0 } else { nb + 1 }],
            tacc: vec![[0.0; 4]; self.runs.as_ref().map_or(0, |r| r.len())],
            hslots: vec![[[0.0; LANES]; 24]; self.hex_blocks.len() + 1],
            tjac: vec![[0.0; LANES]; nb],
            tvj: vec![[0.0; LANES]; nb],
            hjac: vec![[0.0; LANES]; self.hex_blocks.len()],
            jnodal: vec![0.0; self.anp_groups()],
        }
    }
}
