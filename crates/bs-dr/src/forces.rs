//! TLED internal-force kernels (T4, T4ANP, H8 mean strain + hourglass) and their
//! deterministic parallel assembly.
//!
//! Every element writes its nodal forces into its own slots of a per-element buffer (in
//! parallel, with rayon); then every node sums its slots in a fixed, increasing order (in
//! parallel over nodes). No floating-point sum depends on the thread count, so results are
//! bit-identical for 1 and N threads.

use std::sync::atomic::{AtomicBool, Ordering};

use bs_mesh::Vector3;
use nalgebra::Matrix3;

use rayon::prelude::*;

use crate::model::{Model, TetFormulation};

/// Minimum number of elements (or nodes) per rayon task.
const MIN_LEN: usize = 512;

/// Caller-owned scratch buffers for [`Model::internal_forces_into`]; allocate once with
/// [`Model::workspace`] and reuse every step.
#[derive(Debug, Clone)]
pub struct Workspace {
    slots: Vec<Vector3<f64>>,
    /// Per-element `J` (tets, then hexes).
    jac: Vec<f64>,
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

/// `F = I + Σ_a u_a ⊗ g_a` (row i = displacement component, column j = reference direction).
#[inline(always)]
fn deformation_gradient<const N: usize>(
    u: &[Vector3<f64>],
    nodes: &[u32; N],
    g: &[[f64; 3]; N],
) -> Matrix3<f64> {
    let mut f = Matrix3::identity();
    for a in 0..N {
        let ua = &u[nodes[a] as usize];
        for j in 0..3 {
            for i in 0..3 {
                f[(i, j)] += ua[i] * g[a][j];
            }
        }
    }
    f
}

#[inline(always)]
fn det3(f: &Matrix3<f64>) -> f64 {
    f[(0, 0)] * (f[(1, 1)] * f[(2, 2)] - f[(1, 2)] * f[(2, 1)])
        - f[(0, 1)] * (f[(1, 0)] * f[(2, 2)] - f[(1, 2)] * f[(2, 0)])
        + f[(0, 2)] * (f[(1, 0)] * f[(2, 1)] - f[(1, 1)] * f[(2, 0)])
}

/// `out_a = scale · P g_a` for every node (`P` the first Piola–Kirchhoff stress).
#[inline(always)]
fn nodal_forces<const N: usize>(
    p: &Matrix3<f64>,
    scale: f64,
    g: &[[f64; 3]; N],
    out: &mut [Vector3<f64>],
) {
    let p = p * scale;
    for a in 0..N {
        out[a] = p * Vector3::from(g[a]);
    }
}

impl Model {
    /// Scratch buffers sized for this model.
    pub fn workspace(&self) -> Workspace {
        Workspace {
            slots: vec![Vector3::zeros(); self.slot_count()],
            jac: vec![0.0; self.tets.len() + self.hexes.len()],
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
        let (tslots, hslots) = ws.slots.split_at_mut(4 * nt);
        let (tjac, hjac) = ws.jac.split_at_mut(nt);
        match self.options.tet {
            TetFormulation::T4 => {
                tslots
                    .par_chunks_mut(4)
                    .zip(tjac.par_iter_mut())
                    .zip(self.tets.par_iter())
                    .with_min_len(MIN_LEN)
                    .for_each(|((out, jac), t)| {
                        let f = deformation_gradient(u, &t.nodes, &t.g);
                        let j = det3(&f);
                        *jac = j;
                        if !(j > 0.0 && j.is_finite()) {
                            bad.store(true, Ordering::Relaxed);
                            out.iter_mut().for_each(|o| *o = Vector3::zeros());
                            return;
                        }
                        let p = self.solids[t.mat as usize].material.pk1_fj(&f, j);
                        nodal_forces(&p, t.vol, &t.g, out);
                    });
            }
            TetFormulation::T4Anp => {
                // Pass 1: element volume ratios.
                tjac.par_iter_mut().zip(self.tets.par_iter()).with_min_len(MIN_LEN).for_each(
                    |(jac, t)| {
                        let f = deformation_gradient(u, &t.nodes, &t.g);
                        *jac = det3(&f);
                    },
                );
                // Pass 2: nodal volume-weighted averages (fixed order per node).
                let tjac_ro: &[f64] = tjac;
                let tets = &self.tets;
                ws.jnodal.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(n, jn)| {
                    let mut acc = 0.0;
                    let lo = self.gather_ptr[n] as usize;
                    let hi = self.gather_ptr[n + 1] as usize;
                    for &s in &self.gather_slot[lo..hi] {
                        let s = s as usize;
                        if s < 4 * nt {
                            let e = s / 4;
                            acc += tets[e].vol * tjac_ro[e];
                        }
                    }
                    *jn = acc * self.anp_inv_vol[n];
                });
                // Pass 3: stress from F̄ = (J̄/J)^(1/3) F, forces f_a = V (J/J̄)^(1/3) F S̄ g_a
                // (= ∫ σ̄ ∇ₓN_a dv over the current element volume).
                let jnodal: &[f64] = &ws.jnodal;
                tslots
                    .par_chunks_mut(4)
                    .zip(tjac_ro.par_iter())
                    .zip(self.tets.par_iter())
                    .with_min_len(MIN_LEN)
                    .for_each(|((out, &j), t)| {
                        let jbar = 0.25
                            * (jnodal[t.nodes[0] as usize]
                                + jnodal[t.nodes[1] as usize]
                                + jnodal[t.nodes[2] as usize]
                                + jnodal[t.nodes[3] as usize]);
                        if !(j > 0.0 && j.is_finite() && jbar > 0.0 && jbar.is_finite()) {
                            bad.store(true, Ordering::Relaxed);
                            out.iter_mut().for_each(|o| *o = Vector3::zeros());
                            return;
                        }
                        let f = deformation_gradient(u, &t.nodes, &t.g);
                        let r = bs_material::inv_cbrt(j / jbar); // (J̄/J)^(1/3)
                        // P̄ = P(F̄ = r F, J̄); f_a = V r⁻¹ F S̄ g_a = V r⁻² P̄ g_a.
                        let p = self.solids[t.mat as usize].material.pk1_fj(&(f * r), jbar);
                        nodal_forces(&p, t.vol / (r * r), &t.g, out);
                    });
            }
        }
        hslots
            .par_chunks_mut(8)
            .zip(hjac.par_iter_mut())
            .zip(self.hexes.par_iter())
            .with_min_len(MIN_LEN / 4)
            .for_each(|((out, jac), h)| {
                let f = deformation_gradient(u, &h.nodes, &h.g);
                let j = det3(&f);
                *jac = j;
                if !(j > 0.0 && j.is_finite()) {
                    bad.store(true, Ordering::Relaxed);
                    out.iter_mut().for_each(|o| *o = Vector3::zeros());
                    return;
                }
                let p = self.solids[h.mat as usize].material.pk1_fj(&f, j);
                nodal_forces(&p, h.vol, &h.g, out);
                // Hourglass forces K_hg u (per component).
                for a in 0..8 {
                    let mut acc = Vector3::zeros();
                    for b in 0..8 {
                        acc += u[h.nodes[b] as usize] * h.hg[a][b];
                    }
                    out[a] += acc;
                }
            });
        // Gather per node in slot order.
        let slots: &[Vector3<f64>] = &ws.slots;
        forces.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(n, fo)| {
            let lo = self.gather_ptr[n] as usize;
            let hi = self.gather_ptr[n + 1] as usize;
            let mut acc = Vector3::zeros();
            for &s in &self.gather_slot[lo..hi] {
                acc += slots[s as usize];
            }
            *fo = acc;
        });
        if bad.load(Ordering::Relaxed) {
            return Err(self.first_inversion(&ws.jac, &ws.jnodal));
        }
        Ok(())
    }

    fn first_inversion(&self, jac: &[f64], jnodal: &[f64]) -> Inversion {
        let nt = self.tets.len();
        let mut best: Option<Inversion> = None;
        for (k, &j) in jac.iter().enumerate() {
            let (e, jj) = if k < nt {
                let t = &self.tets[k];
                let jbar = if self.options.tet == TetFormulation::T4Anp {
                    0.25 * t.nodes.iter().map(|&n| jnodal[n as usize]).sum::<f64>()
                } else {
                    j
                };
                (self.tet_element(k), if j > 0.0 && j.is_finite() { jbar } else { j })
            } else {
                (self.hex_element(k - nt), j)
            };
            if !(jj > 0.0 && jj.is_finite()) && best.is_none_or(|b| e < b.element) {
                best =
                    Some(Inversion { element: e, element_id: self.element_ids[e], jacobian: jj });
            }
        }
        best.unwrap_or(Inversion {
            element: 0,
            element_id: self.element_ids[0],
            jacobian: f64::NAN,
        })
    }
}
