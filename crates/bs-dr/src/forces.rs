//! Internal forces: runs the element kernels of the private `kernels` module in parallel
//! and assembles their results deterministically.
//!
//! Every element writes its nodal forces into its own slots of a per-element buffer (in
//! parallel, with rayon, over fixed runs of elements); then every node sums its slots in a
//! fixed order (its slots in increasing order, even and odd positions in two partial sums;
//! in parallel over nodes). No floating-point sum depends on the thread count, so results
//! are bit-identical for 1 and N threads.

use std::sync::atomic::{AtomicBool, Ordering};

use bs_mesh::Vector3;
use rayon::prelude::*;

use crate::kernels::h8::{H8Forces, HexBlockForces};
use crate::kernels::layout::LANES;
use crate::kernels::simd::{BlockOp, Lanes, dispatch};
use crate::kernels::t4::T4Forces;
use crate::kernels::t4anp::{AnpForces, Jacobians, nodal_ratio};
use crate::kernels::tet_block::BlockForces;
use crate::model::{Model, TetFormulation};

/// Minimum number of elements (or nodes) per rayon task.
pub(crate) const MIN_LEN: usize = 512;

/// Tet blocks per rayon task (a fixed partition: results do not depend on it).
const BLOCKS_PER_TASK: usize = 64;

/// Hex blocks per rayon task.
const HEX_BLOCKS_PER_TASK: usize = 32;

/// Caller-owned scratch buffers for [`Model::internal_forces_into`]; allocate once with
/// [`Model::workspace`] and reuse every step.
#[derive(Debug, Clone)]
pub struct Workspace {
    /// Displacements padded to `[x, y, z, 0]` (one vector load per node in the kernels).
    upad: Vec<[f64; 4]>,
    /// Tet force slots, per block of four tets, tet-major: slot `4t + a` at `3(4t + a)` of
    /// the flattened buffer (see [`BlockForces`]).
    tslots: Vec<BlockForces>,
    /// Hex force slots, per block of four hexes, hex-major: hex slot `8h + a` at
    /// `3(8h + a)` of the flattened buffer (see [`HexBlockForces`]).
    hslots: Vec<HexBlockForces>,
    /// Tet `J`, blocked.
    tjac: Vec<[f64; LANES]>,
    /// Tet `V J` (T4ANP), blocked.
    tvj: Vec<[f64; LANES]>,
    /// Hex `J`, blocked.
    hjac: Vec<[f64; LANES]>,
    /// ANP nodal volume ratios.
    jnodal: Vec<f64>,
}

/// An element found inverted (`J ≤ 0` or non-finite) while computing forces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inversion {
    /// Element index (mesh order).
    pub element: usize,
    /// External element id.
    pub element_id: u64,
    /// Its `det F`.
    pub jacobian: f64,
}

impl Model {
    /// Scratch buffers sized for this model.
    pub fn workspace(&self) -> Workspace {
        let nb = self.tet_blocks.len();
        Workspace {
            upad: vec![[0.0; 4]; self.node_count()],
            // One spare block and slot: the gather reads every slot as four values.
            tslots: vec![[[0.0; LANES]; 12]; nb + 1],
            hslots: vec![[[0.0; LANES]; 24]; self.hex_blocks.len() + 1],
            tjac: vec![[0.0; LANES]; nb],
            tvj: vec![[0.0; LANES]; nb],
            hjac: vec![[0.0; LANES]; self.hex_blocks.len()],
            jnodal: vec![0.0; self.node_count()],
        }
    }

    /// Internal nodal forces `f_int(u)` (the negative of the residual for zero external
    /// load) into the caller-owned `forces` (one per node), using `ws` as scratch.
    /// Allocation-free; parallel over elements and nodes with rayon on the current thread
    /// pool; bit-identical for any number of threads.
    ///
    /// Returns the lowest-indexed inverted element if any element has `det F ≤ 0` (its forces
    /// are then set to zero and `forces` must not be used).
    pub fn internal_forces_into(
        &self,
        u: &[Vector3<f64>],
        ws: &mut Workspace,
        forces: &mut [Vector3<f64>],
    ) -> Result<(), Inversion> {
        assert_eq!(u.len(), self.node_count(), "displacement length must equal the node count");
        assert_eq!(forces.len(), self.node_count(), "force length must equal the node count");
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
        match self.options.tet {
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
                ws.jnodal.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(n, jn)| {
                    let lo = self.gather_ptr[n] as usize;
                    let slots = &self.gather_slot[lo..lo + self.gather_tets[n] as usize];
                    *jn = nodal_ratio(slots, tvj, self.anp_inv_vol[n]);
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
            dispatch(Gather { model: self, first: chunk * MIN_LEN, tslots, hslots, forces })
        });
        if bad.load(Ordering::Relaxed) {
            let (tjac, hjac) = (ws.tjac.as_flattened(), ws.hjac.as_flattened());
            return Err(self.first_inversion(|t| tjac[t], &hjac[..nh], &ws.jnodal));
        }
        Ok(())
    }

    /// The lowest-indexed element (mesh order) whose `J` (or, for T4ANP tets with a valid
    /// `J`, whose `J̄`) is not > 0 and finite. `tjac(t)` is the `J` of tet `t`.
    pub(crate) fn first_inversion(
        &self,
        tjac: impl Fn(usize) -> f64,
        hjac: &[f64],
        jnodal: &[f64],
    ) -> Inversion {
        let mut best: Option<Inversion> = None;
        let mut consider = |e: usize, jj: f64| {
            if !(jj > 0.0 && jj.is_finite()) && best.is_none_or(|b| e < b.element) {
                best =
                    Some(Inversion { element: e, element_id: self.element_ids[e], jacobian: jj });
            }
        };
        for (k, t) in self.tets.iter().enumerate() {
            let j = tjac(k);
            let jbar = if self.options.tet == TetFormulation::T4Anp {
                0.25 * t.nodes.iter().map(|&n| jnodal[n as usize]).sum::<f64>()
            } else {
                j
            };
            consider(self.tet_element(k), if j > 0.0 && j.is_finite() { jbar } else { j });
        }
        for (k, &j) in hjac.iter().enumerate() {
            consider(self.hex_element(k), j);
        }
        best.unwrap_or(Inversion {
            element: 0,
            element_id: self.element_ids[0],
            jacobian: f64::NAN,
        })
    }
}

/// The gather of a run of nodes starting at `first`: each node's slots in `gather_slot`
/// order, tet slots then hex slots, every slot read as one vector of four (x, y, z and
/// the next value, ignored), summed in two interleaved partial sums (even and odd
/// positions; two independent add chains) added at the end. The order is fixed, so the
/// result does not depend on the thread count.
struct Gather<'a> {
    model: &'a Model,
    first: usize,
    /// Flattened tet slots: slot `s` at `3s`.
    tslots: &'a [f64],
    /// Flattened hex slots: hex slot `h` at `3h`.
    hslots: &'a [f64],
    forces: &'a mut [Vector3<f64>],
}

/// Four values of `buf` from `3 i`.
#[inline(always)]
fn slot4(buf: &[f64], i: usize) -> [f64; 4] {
    buf[3 * i..3 * i + 4].try_into().expect("slot in range")
}

impl BlockOp for Gather<'_> {
    type Output = ();

    #[inline(always)]
    fn run<L: Lanes>(self, l: L) {
        let m = self.model;
        let nt4 = 4 * m.tets.len();
        for (k, fo) in self.forces.iter_mut().enumerate() {
            let n = self.first + k;
            let slots = &m.gather_slot[m.gather_ptr[n] as usize..m.gather_ptr[n + 1] as usize];
            let (ts, hs) = slots.split_at(m.gather_tets[n] as usize);
            let (mut even, mut odd) = (l.splat(0.0), l.splat(0.0));
            let mut pairs = ts.chunks_exact(2);
            for p in &mut pairs {
                even = l.add(even, l.load(slot4(self.tslots, p[0] as usize)));
                odd = l.add(odd, l.load(slot4(self.tslots, p[1] as usize)));
            }
            if let [s] = pairs.remainder() {
                even = l.add(even, l.load(slot4(self.tslots, *s as usize)));
            }
            let mut pairs = hs.chunks_exact(2);
            for p in &mut pairs {
                even = l.add(even, l.load(slot4(self.hslots, p[0] as usize - nt4)));
                odd = l.add(odd, l.load(slot4(self.hslots, p[1] as usize - nt4)));
            }
            if let [s] = pairs.remainder() {
                even = l.add(even, l.load(slot4(self.hslots, *s as usize - nt4)));
            }
            let v = l.store(l.add(even, odd));
            *fo = Vector3::new(v[0], v[1], v[2]);
        }
    }
}
