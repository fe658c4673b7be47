//! The elements of a model as the assembly runs them: tetrahedra then hexahedra (each with
//! its mesh element index), their blocks of four for the SIMD kernels, the solids, the
//! node → slot map and the T4ANP nodal volumes. Built once by `Model::new`.

use crate::element::{ElementView, Hex, Solid, Tet, TetFormulation};
use crate::kernels::layout::{HexBlock, TetBlock, hex_blocks, tet_blocks};

use super::slots::SlotMap;

/// The elements of a model, ready for assembly.
#[derive(Debug, Clone)]
pub(crate) struct Elements {
    /// The solids the elements refer to.
    pub solids: Vec<Solid>,
    /// The formulation of the tetrahedra.
    pub tet: TetFormulation,
    /// The tetrahedra.
    pub tets: Vec<Tet>,
    /// Mesh element index of each tet.
    pub tet_elem: Vec<u32>,
    /// The hexahedra.
    pub hexes: Vec<Hex>,
    /// Mesh element index of each hex.
    pub hex_elem: Vec<u32>,
    /// External element ids (mesh element order).
    pub element_ids: Vec<u64>,
    /// Node → force slots.
    pub slots: SlotMap,
    /// ANP: 1 / Σ_{tets ∋ n} V_e per node (0 for nodes without tets).
    pub anp_inv_vol: Vec<f64>,
    /// `tets` in blocks of four (structure of arrays) for the SIMD kernels; derived from
    /// `tets` and `solids`, padded at the end.
    pub tet_blocks: Vec<TetBlock>,
    /// `hexes` in blocks of four for the SIMD kernel (derived, padded at the end).
    pub hex_blocks: Vec<HexBlock>,
}

/// What [`Elements::new`] is built from.
#[derive(Debug, Clone)]
pub(crate) struct ElementList {
    /// The solids.
    pub solids: Vec<Solid>,
    /// The tetrahedron formulation.
    pub tet: TetFormulation,
    /// Tetrahedra and their mesh element indices.
    pub tets: (Vec<Tet>, Vec<u32>),
    /// Hexahedra and their mesh element indices.
    pub hexes: (Vec<Hex>, Vec<u32>),
    /// External element ids (mesh element order).
    pub element_ids: Vec<u64>,
}

impl Elements {
    /// The assembly data of `list` on `nodes` nodes: slot map, ANP nodal volumes, blocks.
    pub(crate) fn new(list: ElementList, nodes: usize) -> Self {
        let ElementList {
            solids,
            tet,
            tets: (tets, tet_elem),
            hexes: (hexes, hex_elem),
            element_ids,
        } = list;
        let slots = SlotMap::new(nodes, &tets, &hexes);
        let mut anp_vol = vec![0.0; nodes];
        for t in &tets {
            for &n in &t.nodes {
                anp_vol[n as usize] += t.vol;
            }
        }
        let anp_inv_vol = anp_vol.iter().map(|&v| if v > 0.0 { 1.0 / v } else { 0.0 }).collect();
        let tet_blocks = tet_blocks(&tets, &solids);
        let hex_blocks = hex_blocks(&hexes, &solids);
        Elements {
            solids,
            tet,
            tets,
            tet_elem,
            hexes,
            hex_elem,
            element_ids,
            slots,
            anp_inv_vol,
            tet_blocks,
            hex_blocks,
        }
    }

    /// Number of nodes.
    pub(crate) fn nodes(&self) -> usize {
        self.slots.nodes()
    }

    /// Number of force slots (4 per tet, 8 per hex).
    pub(crate) fn slot_count(&self) -> usize {
        4 * self.tets.len() + 8 * self.hexes.len()
    }

    /// Whether the tetrahedra are T4ANP (and there are some).
    pub(crate) fn anp(&self) -> bool {
        self.tet == TetFormulation::T4Anp && !self.tets.is_empty()
    }

    /// Every element with its mesh element index: the tetrahedra, then the hexahedra (the
    /// order of the slots, and of every sum over elements).
    pub(crate) fn iter(&self) -> impl Iterator<Item = (usize, ElementView<'_>)> + '_ {
        let tets = self.tets.iter().zip(&self.tet_elem).map(|(t, &e)| (e as usize, t.view()));
        let hexes = self.hexes.iter().zip(&self.hex_elem).map(|(h, &e)| (e as usize, h.view()));
        tets.chain(hexes)
    }

    /// The element of slot `s` and the local node it stands for.
    #[inline]
    pub(crate) fn slot(&self, s: usize) -> (ElementView<'_>, usize) {
        let nt4 = 4 * self.tets.len();
        if s < nt4 {
            (self.tets[s / 4].view(), s % 4)
        } else {
            (self.hexes[(s - nt4) / 8].view(), (s - nt4) % 8)
        }
    }

    /// Element index (mesh order) of tet `i`.
    pub(crate) fn tet_element(&self, i: usize) -> usize {
        self.tet_elem[i] as usize
    }

    /// Element index (mesh order) of hex `i`.
    pub(crate) fn hex_element(&self, i: usize) -> usize {
        self.hex_elem[i] as usize
    }
}
