//! The node → force-slot map: every element writes its nodal forces into its own slots (tet
//! `t`'s node `a` is slot `4t + a`, then hex `h`'s node `a` is `4·tets + 8h + a`), and every
//! node sums its slots in increasing order. The order is fixed by the mesh alone, so the
//! assembled forces are bit-identical for any thread count.

use crate::element::{Hex, Tet};

/// The slots of every node (compressed rows), tet slots first in each row.
#[derive(Debug, Clone)]
pub(crate) struct SlotMap {
    /// Row offsets (nodes + 1).
    pub ptr: Vec<u32>,
    /// The slots of each node, increasing.
    pub slot: Vec<u32>,
    /// How many of each node's slots are tet slots (they come first).
    pub tets: Vec<u32>,
}

impl SlotMap {
    /// The map of `tets` then `hexes` over `nodes` nodes.
    pub(crate) fn new(nodes: usize, tets: &[Tet], hexes: &[Hex]) -> Self {
        let element_nodes = || {
            tets.iter()
                .flat_map(|t| t.nodes.iter())
                .chain(hexes.iter().flat_map(|h| h.nodes.iter()))
        };
        let mut count = vec![0u32; nodes + 1];
        for &n in element_nodes() {
            count[n as usize + 1] += 1;
        }
        for i in 0..nodes {
            count[i + 1] += count[i];
        }
        let ptr = count.clone();
        let mut fill = count;
        let mut slot = vec![0u32; ptr[nodes] as usize];
        for (s, &n) in element_nodes().enumerate() {
            slot[fill[n as usize] as usize] = s as u32;
            fill[n as usize] += 1;
        }
        let tets = tet_slot_counts(&ptr, &slot, tets.len());
        SlotMap { ptr, slot, tets }
    }

    /// Number of nodes.
    pub(crate) fn nodes(&self) -> usize {
        self.ptr.len() - 1
    }

    /// The slots of node `n`, increasing.
    #[inline(always)]
    pub(crate) fn of(&self, n: usize) -> &[u32] {
        &self.slot[self.ptr[n] as usize..self.ptr[n + 1] as usize]
    }

    /// The tet slots of node `n` (the first of [`of`](Self::of)).
    #[inline(always)]
    pub(crate) fn tet_slots(&self, n: usize) -> &[u32] {
        let lo = self.ptr[n] as usize;
        &self.slot[lo..lo + self.tets[n] as usize]
    }
}

/// Number of tet slots of every node (they come first in its range of `gather_slot`).
fn tet_slot_counts(gather_ptr: &[u32], gather_slot: &[u32], nt: usize) -> Vec<u32> {
    gather_ptr
        .windows(2)
        .map(|w| {
            let slots = &gather_slot[w[0] as usize..w[1] as usize];
            slots.partition_point(|&s| (s as usize) < 4 * nt) as u32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use bs_mesh::Point3;

    use super::*;

    #[test]
    fn every_slot_is_gathered_once_by_its_node_tets_first() {
        let x = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        // The same shape twice, the second with nodes 0 and 1 swapped in the mesh.
        let tets = [Tet::new([0, 1, 2, 3], 0, &x).unwrap(), Tet::new([1, 0, 2, 3], 0, &x).unwrap()];
        let map = SlotMap::new(5, &tets, &[]);
        assert_eq!(map.nodes(), 5);
        let mut all: Vec<u32> = (0..5).flat_map(|n| map.of(n).to_vec()).collect();
        all.sort_unstable();
        assert_eq!(all, (0..8).collect::<Vec<u32>>());
        for n in 0..5 {
            let s = map.of(n);
            assert!(s.windows(2).all(|w| w[0] < w[1]), "node {n}: {s:?}");
            assert_eq!(map.tet_slots(n), s);
            for &k in s {
                assert_eq!(tets[k as usize / 4].nodes[k as usize % 4], n as u32);
            }
        }
        assert!(map.of(4).is_empty());
    }
}
