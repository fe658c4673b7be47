//! Tet forces summed where they are computed. The tet blocks are taken in runs of [`RUN`]
//! consecutive blocks (in Morton order, see `order`, each run is a compact patch of 256
//! tets); a run adds its nodal forces into its own short list of the nodes it touches (a
//! few kilobytes, in the core's cache), and every node then sums its runs' entries in run
//! order. The per-element force slots this replaces (96 bytes a tet, written and read
//! back through main memory) were most of a force evaluation's memory traffic.
//!
//! Every node's sum has a fixed order (its runs in order; within a run, blocks, lanes and
//! corners in order), so the forces are bit-identical for any thread count. Used for
//! meshes of tetrahedra only (hexahedra keep the slots).

use crate::kernels::layout::{LANES, TetBlock};

/// Blocks per run (and per rayon task of the force kernels).
pub(crate) const RUN: usize = 64;

/// Where each run's nodal forces go and which entries each node sums.
#[derive(Debug, Clone)]
pub(crate) struct RunMap {
    /// Entries per run: run `r` owns entries `r · cap .. (r + 1) · cap`.
    pub cap: usize,
    /// Per block, corner and lane: the corner's node among its run's (`local[b][a][l]`).
    pub local: Vec<[[u16; LANES]; 4]>,
    /// The entries of node `n`: `entry[ptr[n]..ptr[n + 1]]`, increasing.
    pub ptr: Vec<u32>,
    pub entry: Vec<u32>,
}

impl RunMap {
    /// The map of `blocks` (corners on `nodes` nodes, padded lanes included: their forces
    /// are zero).
    pub(crate) fn new(blocks: &[TetBlock], nodes: usize) -> RunMap {
        let mut seen = vec![u32::MAX; nodes];
        let mut local_of = vec![0u16; nodes];
        let mut local = Vec::with_capacity(blocks.len());
        let mut lists: Vec<Vec<u32>> = Vec::with_capacity(blocks.len().div_ceil(RUN));
        for (r, run) in blocks.chunks(RUN).enumerate() {
            let mut list = Vec::new();
            for b in run {
                local.push(std::array::from_fn(|a| {
                    std::array::from_fn(|l| {
                        let n = b.nodes[a][l] as usize;
                        if seen[n] != r as u32 {
                            seen[n] = r as u32;
                            local_of[n] = list.len() as u16;
                            list.push(n as u32);
                        }
                        local_of[n]
                    })
                }));
            }
            lists.push(list);
        }
        let cap = lists.iter().map(Vec::len).max().unwrap_or(0);
        let mut count = vec![0u32; nodes + 1];
        for &n in lists.iter().flatten() {
            count[n as usize + 1] += 1;
        }
        for n in 0..nodes {
            count[n + 1] += count[n];
        }
        let ptr = count.clone();
        let mut entry = vec![0u32; ptr[nodes] as usize];
        for (r, list) in lists.iter().enumerate() {
            for (k, &n) in list.iter().enumerate() {
                entry[count[n as usize] as usize] = (r * cap + k) as u32;
                count[n as usize] += 1;
            }
        }
        RunMap { cap, local, ptr, entry }
    }

    /// Number of entries (runs × `cap`).
    pub(crate) fn len(&self) -> usize {
        self.local.len().div_ceil(RUN) * self.cap
    }

    /// The entries of node `n`, in run order.
    #[inline(always)]
    pub(crate) fn of(&self, n: usize) -> &[u32] {
        &self.entry[self.ptr[n] as usize..self.ptr[n + 1] as usize]
    }
}

/// Adds the forces `out` of the run's blocks (`local` their corners' entries) into the
/// run's entries `acc`, which it first zeroes.
#[inline]
pub(crate) fn accumulate(
    local: &[[[u16; LANES]; 4]],
    out: &[crate::kernels::tet_block::BlockForces],
    acc: &mut [[f64; 4]],
) {
    acc.fill([0.0; 4]);
    for (loc, o) in local.iter().zip(out) {
        let v = o.as_flattened();
        for l in 0..LANES {
            for a in 0..4 {
                let f = &v[12 * l + 3 * a..12 * l + 3 * a + 3];
                let e = &mut acc[loc[a][l] as usize];
                e[0] += f[0];
                e[1] += f[1];
                e[2] += f[2];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::layout::BlockLaw;

    fn block(nodes: [[u32; LANES]; 4]) -> TetBlock {
        TetBlock {
            g: [[0.0; LANES]; 9],
            vol: [0.0; LANES],
            nodes,
            anp: nodes,
            law: BlockLaw::PerElement,
        }
    }

    #[test]
    fn every_corner_has_one_entry_of_its_run_and_nodes_list_theirs_in_run_order() {
        // RUN + 1 blocks: two runs; node 0 in both, node 9 only in the second.
        let mut blocks = vec![block([[0, 1, 2, 3], [1, 2, 3, 4], [2, 3, 4, 5], [3, 4, 5, 6]]); RUN];
        blocks.push(block([[9, 0, 9, 0], [7, 7, 7, 7], [8, 8, 8, 8], [0, 0, 0, 0]]));
        let m = RunMap::new(&blocks, 10);
        assert_eq!(m.cap, 7);
        assert_eq!(m.len(), 14);
        for (b, blk) in blocks.iter().enumerate() {
            let run = b / RUN;
            for a in 0..4 {
                for l in 0..LANES {
                    let e = run * m.cap + m.local[b][a][l] as usize;
                    assert!(m.of(blk.nodes[a][l] as usize).contains(&(e as u32)));
                }
            }
        }
        assert_eq!(m.of(0), &[0, 7 + 1]);
        assert_eq!(m.of(9), &[7]);
        assert!(m.of(9).len() == 1 && m.of(5).len() == 1);
    }

    #[test]
    fn a_runs_forces_are_summed_per_node_in_order() {
        let blocks = vec![block([[0, 1, 0, 0], [1, 2, 1, 1], [2, 3, 2, 2], [3, 0, 3, 3]])];
        let m = RunMap::new(&blocks, 4);
        let mut out = [[[0.0; LANES]; 12]];
        // Lane l, corner a, component c = 100 l + 10 a + c.
        for (i, v) in out[0].as_flattened_mut().iter_mut().enumerate() {
            let (l, a, c) = (i / 12, (i % 12) / 3, i % 3);
            *v = (100 * l + 10 * a + c) as f64;
        }
        let mut acc = vec![[f64::NAN; 4]; m.cap];
        accumulate(&m.local, &out, &mut acc);
        // Node 0 is corner 0 of lanes 0, 2, 3 and corner 3 of lane 1.
        let node0 = acc[m.local[0][0][0] as usize];
        assert_eq!(
            node0,
            [
                0.0 + 130.0 + 200.0 + 300.0,
                1.0 + 131.0 + 201.0 + 301.0,
                2.0 + 132.0 + 202.0 + 302.0,
                0.0
            ]
        );
        // Every entry was written (the NaNs zeroed first).
        assert!(acc.iter().all(|e| e.iter().all(|v| v.is_finite())));
    }
}
