//! The scalar reference assembly: the one-element-at-a-time kernels of
//! `kernels::reference` run over the elements and gathered per node, with the same contract
//! as the SIMD path (`forces.rs`). The reference the vectorised path is tested against and
//! the benchmark's baseline.

use std::sync::atomic::{AtomicBool, Ordering};

use bs_mesh::Vector3;
use rayon::prelude::*;

use crate::element::TetFormulation;
use crate::kernels::reference::{anp_jbar, h8_element, t4_element, t4anp_element, tet_jacobian};

use super::elements::Elements;
use super::forces::MIN_LEN;
use super::inversion::Inversion;

/// Scratch buffers of the scalar reference assembly (`Model::internal_forces_scalar_into`).
#[doc(hidden)]
#[derive(Debug, Clone)]
pub struct ReferenceWorkspace {
    slots: Vec<Vector3<f64>>,
    /// Per-element `J` (tets, then hexes).
    jac: Vec<f64>,
    /// ANP nodal volume ratios.
    jnodal: Vec<f64>,
}

impl Elements {
    /// Scratch buffers for [`internal_forces_scalar_into`](Self::internal_forces_scalar_into).
    pub(crate) fn reference_workspace(&self) -> ReferenceWorkspace {
        ReferenceWorkspace {
            slots: vec![Vector3::zeros(); self.slot_count()],
            jac: vec![0.0; self.tets.len() + self.hexes.len()],
            jnodal: vec![0.0; self.anp_groups()],
        }
    }

    /// The scalar reference kernels (one element at a time, three T4ANP passes), with the
    /// same contract as [`internal_forces_into`](Self::internal_forces_into). For tests and
    /// the benchmark's baseline only.
    pub(crate) fn internal_forces_scalar_into(
        &self,
        u: &[Vector3<f64>],
        ws: &mut ReferenceWorkspace,
        forces: &mut [Vector3<f64>],
    ) -> Result<(), Inversion> {
        assert_eq!(u.len(), self.nodes(), "displacement length must equal the node count");
        assert_eq!(forces.len(), self.nodes(), "force length must equal the node count");
        let nt = self.tets.len();
        let bad = AtomicBool::new(false);
        let (tslots, hslots) = ws.slots.split_at_mut(4 * nt);
        let (tjac, hjac) = ws.jac.split_at_mut(nt);
        match self.tet {
            TetFormulation::T4 => {
                tslots
                    .par_chunks_mut(4)
                    .zip(tjac.par_iter_mut())
                    .zip(self.tets.par_iter())
                    .with_min_len(MIN_LEN)
                    .for_each(|((out, jac), t)| {
                        *jac = t4_element(&self.solids[t.mat as usize].material, u, t, out);
                        if !(*jac > 0.0 && jac.is_finite()) {
                            bad.store(true, Ordering::Relaxed);
                        }
                    });
            }
            TetFormulation::T4Anp => {
                tjac.par_iter_mut()
                    .zip(self.tets.par_iter())
                    .with_min_len(MIN_LEN)
                    .for_each(|(jac, t)| *jac = tet_jacobian(u, t));
                let tjac_ro: &[f64] = tjac;
                let tets = &self.tets;
                ws.jnodal.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(g, jn)| {
                    let mut acc = 0.0;
                    for &s in self.anp_slots(g) {
                        let e = s as usize / 4;
                        acc += tets[e].vol * tjac_ro[e];
                    }
                    *jn = acc * self.anp_inv_vol[g];
                });
                let jnodal: &[f64] = &ws.jnodal;
                tslots
                    .par_chunks_mut(4)
                    .zip(tjac_ro.par_iter())
                    .zip(self.tets.par_iter())
                    .with_min_len(MIN_LEN)
                    .for_each(|((out, &j), t)| {
                        let jbar = anp_jbar(jnodal, &t.anp);
                        let m = &self.solids[t.mat as usize].material;
                        if !t4anp_element(m, u, t, j, jbar, out) {
                            bad.store(true, Ordering::Relaxed);
                        }
                    });
            }
        }
        hslots
            .par_chunks_mut(8)
            .zip(hjac.par_iter_mut())
            .zip(self.hexes.par_iter())
            .with_min_len(MIN_LEN / 4)
            .for_each(|((out, jac), h)| {
                *jac = h8_element(&self.solids[h.mat as usize].material, u, h, out);
                if !(*jac > 0.0 && jac.is_finite()) {
                    bad.store(true, Ordering::Relaxed);
                }
            });
        let slots: &[Vector3<f64>] = &ws.slots;
        forces.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(n, fo)| {
            let mut acc = Vector3::zeros();
            for &s in self.slots.of(n) {
                acc += slots[s as usize];
            }
            *fo = acc;
        });
        if bad.load(Ordering::Relaxed) {
            let (tjac, hjac) = ws.jac.split_at(nt);
            return Err(self.first_inversion(|t| tjac[t], hjac, &ws.jnodal));
        }
        Ok(())
    }
}
