//! Internal forces: runs the element kernels of the `kernels` layer in parallel and
//! assembles their results deterministically.
//!
//! Every element writes its nodal forces into its own slots of a per-element buffer (in
//! parallel, with rayon, over fixed runs of elements); then every node sums its slots in a
//! fixed order (its slots in increasing order, even and odd positions in two partial sums;
//! in parallel over nodes). No floating-point sum depends on the thread count, so results
//! are bit-identical for 1 and N threads.

use std::sync::atomic::{AtomicBool, Ordering};

use bs_mesh::Vector3;
use rayon::prelude::*;

use crate::element::TetFormulation;
use crate::kernels::h8::H8Forces;
use crate::kernels::layout::LANES;
use crate::kernels::simd::dispatch;
use crate::kernels::t4::T4Forces;
use crate::kernels::t4anp::{AnpForces, Jacobians, nodal_ratio};

use super::elements::Elements;
use super::gather::Gather;
use super::inversion::Inversion;
use super::workspace::Workspace;

/// Minimum number of elements (or nodes) per rayon task.
pub(crate) const MIN_LEN: usize = 512;

/// Tet blocks per rayon task (a fixed partition: results do not depend on it).
const BLOCKS_PER_TASK: usize = 64;

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
        let nt = self.tets.len();
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
        let upad: &[[f64; 4]] = &ws.upad;
        let tets_of = |task: usize, len: usize| {
            let lo = (task * BLOCKS_PER_TASK * LANES).min(nt);
            &self.tets[lo..(lo + len * LANES).min(nt)]
        };
        match self.tet {
            TetFormulation::T4 => {
                self.tet_blocks
                    .par_chunks(BLOCKS_PER_TASK)
                    .zip(ws.tslots.par_chunks_mut(BLOCKS_PER_TASK))
                    .zip(ws.tjac.par_chunks_mut(BLOCKS_PER_TASK))
                    .enumerate()
                    .for_each(|(task, ((blocks, out), jac))| {
                        flag(dispatch(T4Forces {
                            blocks,
                            tets: tets_of(task, blocks.len()),
                            solids: &self.solids,
                            u,
                            upad,
                            out,
                            jac,
                        }))
                    });
            }
            TetFormulation::T4Anp => {
                // Pass 1: J and V J.
                self.tet_blocks
                    .par_chunks(BLOCKS_PER_TASK)
                    .zip(ws.tjac.par_chunks_mut(BLOCKS_PER_TASK))
                    .zip(ws.tvj.par_chunks_mut(BLOCKS_PER_TASK))
                    .for_each(|((blocks, jac), vj)| dispatch(Jacobians { blocks, upad, jac, vj }));
                // Pass 2: nodal volume-weighted averages (fixed order per node).
                let tvj: &[[f64; LANES]] = &ws.tvj;
                ws.jnodal.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(g, jn)| {
                    *jn = nodal_ratio(self.anp_slots(g), tvj, self.anp_inv_vol[g]);
                });
                // Pass 3: J̄ and the forces.
                let (jnodal, tjac): (&[f64], &[[f64; LANES]]) = (&ws.jnodal, &ws.tjac);
                self.tet_blocks
                    .par_chunks(BLOCKS_PER_TASK)
                    .zip(ws.tslots.par_chunks_mut(BLOCKS_PER_TASK))
                    .zip(tjac.par_chunks(BLOCKS_PER_TASK))
                    .enumerate()
                    .for_each(|(task, ((blocks, out), jac))| {
                        flag(dispatch(AnpForces {
                            blocks,
                            tets: tets_of(task, blocks.len()),
                            solids: &self.solids,
                            u,
                            upad,
                            jac,
                            jnodal,
                            out,
                        }))
                    });
            }
        }
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
        if bad.load(Ordering::Relaxed) {
            let (tjac, hjac) = (ws.tjac.as_flattened(), ws.hjac.as_flattened());
            return Err(self.first_inversion(|t| tjac[t], &hjac[..nh], &ws.jnodal));
        }
        Ok(())
    }
}
