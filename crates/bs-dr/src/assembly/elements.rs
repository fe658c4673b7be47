//! The elements of a model as the assembly runs them: tetrahedra then hexahedra (each with
//! its mesh element index), their blocks of four for the SIMD kernels, the solids, the
//! node → slot map and the T4ANP nodal volumes. Built once by `Model::new`.

use rayon::prelude::*;

use crate::element::{ElementView, Hex, Solid, Tet, TetFormulation};
use crate::kernels::layout::{HexBlock, TetBlock, hex_blocks, tet_blocks};

use super::runs::RunMap;
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
    /// ANP: 1 / Σ_{tets of group g} V_e per averaging group (0 for nodes without tets).
    pub anp_inv_vol: Vec<f64>,
    /// ANP: the tet slots of each averaging group (`anp_ptr[g]..anp_ptr[g + 1]`), in the
    /// order of their node's slots.
    pub anp_slots: Vec<u32>,
    pub anp_ptr: Vec<u32>,
    /// `tets` in blocks of four (structure of arrays) for the SIMD kernels; derived from
    /// `tets` and `solids`, padded at the end.
    pub tet_blocks: Vec<TetBlock>,
    /// `hexes` in blocks of four for the SIMD kernel (derived, padded at the end).
    pub hex_blocks: Vec<HexBlock>,
    /// Where the tet blocks' forces are summed, for a mesh of tetrahedra only (`None`: the
    /// slots).
    pub runs: Option<RunMap>,
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
        let mut tets = tets;
        let groups = anp_groups(&mut tets, nodes);
        let slots = SlotMap::new(nodes, &tets, &hexes);
        let (anp_slots, anp_ptr) = group_slots(&slots, &tets, nodes, groups);
        let mut anp_vol = vec![0.0; groups];
        for t in &tets {
            for &g in &t.anp {
                anp_vol[g as usize] += t.vol;
            }
        }
        let anp_inv_vol = anp_vol.iter().map(|&v| if v > 0.0 { 1.0 / v } else { 0.0 }).collect();
        let tet_blocks = tet_blocks(&tets, &solids);
        let hex_blocks = hex_blocks(&hexes, &solids);
        let runs = (hexes.is_empty() && !tets.is_empty()).then(|| RunMap::new(&tet_blocks, nodes));
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
            anp_slots,
            anp_ptr,
            tet_blocks,
            hex_blocks,
            runs,
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

    /// Number of T4ANP averaging groups (at least the node count).
    pub(crate) fn anp_groups(&self) -> usize {
        self.anp_inv_vol.len()
    }

    /// The tet slots of averaging group `g`.
    #[inline(always)]
    pub(crate) fn anp_slots(&self, g: usize) -> &[u32] {
        &self.anp_slots[self.anp_ptr[g] as usize..self.anp_ptr[g + 1] as usize]
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

    /// [`iter`](Self::iter) in parallel, in the same order when collected.
    pub(crate) fn par_iter(
        &self,
    ) -> impl IndexedParallelIterator<Item = (usize, ElementView<'_>)> + '_ {
        let tets = self
            .tets
            .par_iter()
            .zip(self.tet_elem.par_iter())
            .map(|(t, &e)| (e as usize, t.view()));
        let hexes = self
            .hexes
            .par_iter()
            .zip(self.hex_elem.par_iter())
            .map(|(h, &e)| (e as usize, h.view()));
        tets.chain(hexes)
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

/// Sets the T4ANP averaging group of every tet corner and returns the number of groups. The
/// volume ratio is averaged over the tets around a node of the same solid only: averaging
/// across a material interface would mix the volume changes of two materials (a soft region
/// next to a stiff one then takes part of the stiff one's constraint). Group `n` is node `n`
/// with the solid of its first tet, so a one-solid mesh has one group per node, numbered as
/// the nodes; a node shared by `k` solids has `k − 1` further groups after them.
fn anp_groups(tets: &mut [Tet], nodes: usize) -> usize {
    let mut first = vec![u32::MAX; nodes];
    let mut extra: std::collections::BTreeMap<(u32, u32), u32> = Default::default();
    let mut count = nodes as u32;
    for t in tets.iter_mut() {
        for c in 0..4 {
            let n = t.nodes[c];
            let solid = &mut first[n as usize];
            if *solid == u32::MAX {
                *solid = t.mat;
            }
            t.anp[c] = if *solid == t.mat {
                n
            } else {
                *extra.entry((n, t.mat)).or_insert_with(|| {
                    count += 1;
                    count - 1
                })
            };
        }
    }
    count as usize
}

/// The tet slots of each averaging group in the order of its node's slots (CSR).
fn group_slots(slots: &SlotMap, tets: &[Tet], nodes: usize, groups: usize) -> (Vec<u32>, Vec<u32>) {
    let group_of = |s: u32| tets[s as usize / 4].anp[s as usize % 4] as usize;
    let mut count = vec![0u32; groups];
    for n in 0..nodes {
        for &s in slots.tet_slots(n) {
            count[group_of(s)] += 1;
        }
    }
    let mut ptr = vec![0u32; groups + 1];
    for g in 0..groups {
        ptr[g + 1] = ptr[g] + count[g];
    }
    let mut fill = ptr.clone();
    let mut out = vec![0u32; ptr[groups] as usize];
    for n in 0..nodes {
        for &s in slots.tet_slots(n) {
            let g = group_of(s);
            out[fill[g] as usize] = s;
            fill[g] += 1;
        }
    }
    (out, ptr)
}
