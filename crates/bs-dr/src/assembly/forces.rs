//! Internal forces: runs the element kernels of the `kernels` layer in parallel and
//! assembles their results deterministically.
//!
//! A mesh of tetrahedra sums its forces per run of blocks where they are computed, then per
//! node over its runs ([`runs`](super::runs)). Otherwise every element writes its nodal
//! forces into its own slots of a per-element buffer (in parallel, with rayon, over fixed
//! runs of elements); then every node sums its slots in a fixed order (its slots in
//! increasing order, even and odd positions in two partial sums; in parallel over nodes).
//! No floating-point sum depends on the thread count, so results are bit-identical for 1
//! and N threads.

use std::sync::atomic::{AtomicBool, Ordering};

use bs_mesh::Vector3;
use rayon::prelude::*;

use crate::element::{Tet, TetFormulation};
use crate::kernels::h8::H8Forces;
use crate::kernels::layout::{LANES, TetBlock};
use crate::kernels::simd::dispatch;
use crate::kernels::t4::T4Forces;
use crate::kernels::t4anp::{AnpForces, Jacobians, nodal_ratio};
use crate::kernels::tet_block::BlockForces;

use super::elements::Elements;
use super::gather::Gather;
use super::inversion::Inversion;
use super::runs::{RUN, RunMap, accumulate};
use super::workspace::Workspace;

/// Minimum number of elements (or nodes) per rayon task.
pub(crate) const MIN_LEN: usize = 512;

/// Tet blocks per rayon task (a fixed partition: results do not depend on it), the runs'.
const BLOCKS_PER_TASK: usize = RUN;

/// Hex blocks per rayon task.
const HEX_BLOCKS_PER_TASK: usize = 32;

impl Elements {
    /// Internal nodal forces `f_int(u)` (the negative of the residual for zero external
    /// load) into the caller-owned `forces` (one per node), using `ws` as scratch (see
    /// `Model::internal_forces_into`).
    /// Allocation-free; parallel over elements and nodes with rayon on the current thread
    /// pool; bit-identical for any number of threads.
    ///
    /// Returns the lowest-indexed inverted element if any element has `det F ≤ 0` (its forces
    /// are then set to zero and `forces` must not be used).
    pub(crate) fn internal_forces_into(
        &self,
        u: &[Vector3<f64>],
        ws: &mut Workspace,
        forces: &mut [Vector3<f64>],
    ) -> Result<(), Inversion> {
        assert_eq!(u.len(), self.nodes(), "displacement length must equal the node count");
        assert_eq!(forces.len(), self.nodes(), "force length must equal the node count");
        let bad = AtomicBool::new(false);
        let flag = |b: bool| {
            if b {
                bad.store(true, Ordering::Relaxed);
            }
        };
        ws.upad
            .par_iter_mut()
            .zip(u.par_iter())
            .with_min_len(4 * MIN_LEN)
            .for_each(|(p, v)| *p = [v.x, v.y, v.z, 0.0]);
        if self.tet == TetFormulation::T4Anp {
            // Passes 1 and 2: J, V J and the nodal volume-weighted averages (fixed order).
            self.tet_blocks
                .par_chunks(BLOCKS_PER_TASK)
                .zip(ws.tjac.par_chunks_mut(BLOCKS_PER_TASK))
                .zip(ws.tvj.par_chunks_mut(BLOCKS_PER_TASK))
                .for_each(|((blocks, jac), vj)| {
                    dispatch(Jacobians { blocks, upad: &ws.upad, jac, vj })
                });
            let tvj: &[[f64; LANES]] = &ws.tvj;
            ws.jnodal.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(g, jn)| {
                *jn = nodal_ratio(self.anp_slots(g), tvj, self.anp_inv_vol[g]);
            });
        }
        match &self.runs {
            Some(runs) => {
                self.tet_forces_runs(runs, u, ws, &flag);
                let tacc: &[[f64; 4]] = &ws.tacc;
                forces.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(n, fo)| {
                    let mut s = [0.0; 3];
                    for &e in runs.of(n) {
                        let a = &tacc[e as usize];
                        s = [s[0] + a[0], s[1] + a[1], s[2] + a[2]];
                    }
                    *fo = Vector3::from(s);
                });
            }
            None => self.forces_slots(u, ws, &flag, forces),
        }
        if bad.load(Ordering::Relaxed) {
            let (tjac, hjac) = (ws.tjac.as_flattened(), ws.hjac.as_flattened());
            return Err(self.first_inversion(|t| tjac[t], &hjac[..self.hexes.len()], &ws.jnodal));
        }
        Ok(())
    }

    /// The tets of task `task` (of [`BLOCKS_PER_TASK`] blocks) holding `len` blocks.
    fn tets_of(&self, task: usize, len: usize) -> &[Tet] {
        let nt = self.tets.len();
        let lo = (task * BLOCKS_PER_TASK * LANES).min(nt);
        &self.tets[lo..(lo + len * LANES).min(nt)]
    }

    /// One task's tet forces into `out` (T4, or T4ANP's pass 3 after passes 1 and 2), and
    /// `J` into `jac` for T4; whether a lane inverted.
    #[allow(clippy::too_many_arguments)]
    fn tet_task(
        &self,
        task: usize,
        blocks: &[TetBlock],
        u: &[Vector3<f64>],
        upad: &[[f64; 4]],
        jnodal: &[f64],
        jac: &mut [[f64; LANES]],
        out: &mut [BlockForces],
    ) -> bool {
        let (tets, solids) = (self.tets_of(task, blocks.len()), &self.solids);
        match self.tet {
            TetFormulation::T4 => dispatch(T4Forces { blocks, tets, solids, u, upad, out, jac }),
            TetFormulation::T4Anp => {
                dispatch(AnpForces { blocks, tets, solids, u, upad, jac, jnodal, out })
            }
        }
    }

    /// The tet forces summed per run into `ws.tacc`.
    fn tet_forces_runs(
        &self,
        runs: &RunMap,
        u: &[Vector3<f64>],
        ws: &mut Workspace,
        flag: &(dyn Fn(bool) + Sync),
    ) {
        let (upad, jnodal): (&[[f64; 4]], &[f64]) = (&ws.upad, &ws.jnodal);
        self.tet_blocks
            .par_chunks(RUN)
            .zip(ws.tjac.par_chunks_mut(RUN))
            .zip(ws.tacc.par_chunks_mut(runs.cap))
            .zip(runs.local.par_chunks(RUN))
            .enumerate()
            .for_each(|(task, (((blocks, jac), acc), local))| {
                let mut out: [BlockForces; RUN] = [[[0.0; LANES]; 12]; RUN];
                let out = &mut out[..blocks.len()];
                flag(self.tet_task(task, blocks, u, upad, jnodal, jac, out));
                accumulate(local, out, acc);
            });
    }

    /// Tet and hex forces into their slots, gathered per node into `forces`.
    fn forces_slots(
        &self,
        u: &[Vector3<f64>],
        ws: &mut Workspace,
        flag: &(dyn Fn(bool) + Sync),
        forces: &mut [Vector3<f64>],
    ) {
        let (upad, jnodal): (&[[f64; 4]], &[f64]) = (&ws.upad, &ws.jnodal);
        self.tet_blocks
            .par_chunks(BLOCKS_PER_TASK)
            .zip(ws.tslots.par_chunks_mut(BLOCKS_PER_TASK))
            .zip(ws.tjac.par_chunks_mut(BLOCKS_PER_TASK))
            .enumerate()
            .for_each(|(task, ((blocks, out), jac))| {
                flag(self.tet_task(task, blocks, u, upad, jnodal, jac, out));
            });
        let nh = self.hexes.len();
        self.hex_blocks
            .par_chunks(HEX_BLOCKS_PER_TASK)
            .zip(ws.hslots.par_chunks_mut(HEX_BLOCKS_PER_TASK))
            .zip(ws.hjac.par_chunks_mut(HEX_BLOCKS_PER_TASK))
            .enumerate()
            .for_each(|(task, ((blocks, out), jac))| {
                let lo = (task * HEX_BLOCKS_PER_TASK * LANES).min(nh);
                let hexes = &self.hexes[lo..(lo + blocks.len() * LANES).min(nh)];
                let solids = &self.solids;
                flag(dispatch(H8Forces { blocks, hexes, solids, u, upad, out, jac }))
            });
        // Gather per node in slot order: tet slots, then hex slots.
        let tslots = ws.tslots.as_flattened().as_flattened();
        let hslots = ws.hslots.as_flattened().as_flattened();
        forces.par_chunks_mut(MIN_LEN).enumerate().for_each(|(chunk, forces)| {
            dispatch(Gather { elements: self, first: chunk * MIN_LEN, tslots, hslots, forces })
        });
    }
}
