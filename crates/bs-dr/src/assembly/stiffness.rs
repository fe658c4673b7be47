//! The small-strain stiffness `K₀` of a model at its reference state: what the Newton–Krylov
//! solver's preconditioner is built from.
//!
//! Every law linearises at `F = I` to isotropic elasticity with the shear modulus `μ` and
//! bulk modulus `κ` of [`bs_material::Material::elastic`]. T4 and H8 elements contribute
//! their element stiffness `V Bᵀ D B` (H8 with its hourglass matrix on each component).
//! The average-nodal-pressure tetrahedron linearises to its deviatoric element stiffness plus
//! a nodal volumetric term: with `c_n = Σ_{e∋n} V_e ∇J_e / V_n` the gradient of the nodal
//! volume ratio and `V_n = Σ_{e∋n} V_e`, the force kernel's volumetric part is
//! `Σ_e V_e κ_e ∇J_e (¼ Σ_{n∈e} c_n)ᵀ = Σ_n (V_n κ̄_n / 4) c_n c_nᵀ` (exact for one `κ`; with
//! several regions `κ̄_n` is the volume average at the node, a symmetric approximation).
//! That term is kept as a [`RankOneSum`], never assembled: it would couple each node with its
//! two-ring. `K₀` is returned as a [`NodalMatrix`] (the assembled element part plus the
//! nodal term).
//!
//! The sibling module `stiffness_at` moves the same small-strain stiffness to a deformed configuration
//! in place (the elements' gradients and volumes at `X + u`, the reference moduli): the
//! preconditioner following the state, where `K₀` drifts from the tangent.

use bs_mesh::Vector3;
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::linalg::nodal::NodalMatrix;
use crate::linalg::sparse::{BlockCsr, RankOneSum, split_rows};

use super::elements::Elements;
use crate::element::{Hex, Tet};

/// `K_ab = V (λ gₐ⊗g_b + μ g_b⊗gₐ + μ (gₐ·g_b) I)`: the isotropic small-strain stiffness block
/// coupling nodes `a` and `b` of an element with (mean) gradients `ga`, `gb`.
#[inline]
fn block(ga: &[f64; 3], gb: &[f64; 3], lambda: f64, mu: f64, vol: f64) -> Matrix3<f64> {
    let dot = ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2];
    Matrix3::from_fn(|i, j| {
        vol * (lambda * ga[i] * gb[j] + mu * ga[j] * gb[i] + if i == j { mu * dot } else { 0.0 })
    })
}

/// Assembles `K₀` of `elements` (all nodes, no boundary conditions): the element stiffness
/// (deviatoric only for T4ANP tetrahedra) and, for T4ANP, the nodal volumetric term.
pub(crate) fn linear_stiffness(elements: &Elements) -> NodalMatrix {
    let mut k = BlockCsr::from_pattern(&adjacency(elements));
    assemble_rows(elements, &elements.tets, &elements.hexes, &mut k);
    let (nodal, ratio) = match elements.anp().then(|| nodal_volumetric(elements)) {
        Some((nodal, ratio)) => (Some(nodal), ratio),
        None => (None, Vec::new()),
    };
    NodalMatrix { assembled: k, nodal, ratio }
}

/// The element part of the stiffness of `tets` and `hexes` (the elements of `elements`, or
/// the same elements on another configuration) written into `k`, whose pattern is the node
/// graph of `elements`: row-parallel through the node → element-slot map, each row's
/// blocks summed in the slots' order (deterministic for any thread count).
pub(super) fn assemble_rows(elements: &Elements, tets: &[Tet], hexes: &[Hex], k: &mut BlockCsr) {
    let anp = elements.anp();
    let nt4 = 4 * tets.len();
    let BlockCsr { ptr, col, val } = k;
    let rows = split_rows(ptr, val);
    let (ptr, col) = (&*ptr, &*col);
    rows.into_par_iter().enumerate().with_min_len(128).for_each(|(r, row)| {
        row.iter_mut().for_each(|b| *b = Matrix3::zeros());
        let cols = &col[ptr[r] as usize..ptr[r + 1] as usize];
        let pos = |c: u32| cols.binary_search(&c).expect("node pair in the adjacency pattern");
        for &s in elements.slots.of(r) {
            let s = s as usize;
            let (e, a) = if s < nt4 {
                (tets[s / 4].view(), s % 4)
            } else {
                (hexes[(s - nt4) / 8].view(), (s - nt4) % 8)
            };
            let el = elements.solids[e.mat].material.elastic();
            let lambda = if anp && e.hg.is_none() { -2.0 / 3.0 * el.mu } else { el.lambda() };
            for b in 0..e.len() {
                let mut kb = block(&e.g[a], &e.g[b], lambda, el.mu, e.vol);
                if let Some(hg) = e.hg {
                    for i in 0..3 {
                        kb[(i, i)] += hg[a][b];
                    }
                }
                row[pos(e.nodes[b])] += kb;
            }
        }
    });
}

/// The node graph of the element connectivity: every row sorted, the diagonal included.
fn adjacency(elements: &Elements) -> Vec<Vec<u32>> {
    let mut adjacency: Vec<Vec<u32>> = vec![Vec::new(); elements.nodes()];
    for (_, e) in elements.iter() {
        for &a in e.nodes {
            adjacency[a as usize].extend_from_slice(e.nodes);
        }
    }
    adjacency.par_iter_mut().for_each(|row| {
        row.sort_unstable();
        row.dedup();
    });
    adjacency
}

/// The T4ANP nodal volumetric term `Σ_n (V_n κ̄_n / 4) c_n c_nᵀ` (see the module docs), and
/// `κ̄_n / μ̄_n` per term.
fn nodal_volumetric(elements: &Elements) -> (RankOneSum, Vec<f64>) {
    let n = elements.nodes();
    type Row = ((f64, f64), Vec<(u32, Vector3<f64>)>);
    let rows: Vec<Row> = (0..elements.anp_groups())
        .into_par_iter()
        .with_min_len(128)
        .map(|r| {
            let mut vol = 0.0;
            let mut vk = 0.0;
            let mut vmu = 0.0;
            let mut entries: Vec<(u32, Vector3<f64>)> = Vec::new();
            for &s in elements.anp_slots(r) {
                let t = &elements.tets[s as usize / 4];
                vol += t.vol;
                let el = elements.solids[t.mat as usize].material.elastic();
                vk += t.vol * el.kappa;
                vmu += t.vol * el.mu;
                for b in 0..4 {
                    entries.push((t.nodes[b], Vector3::from(t.g[b]) * t.vol));
                }
            }
            if vol == 0.0 {
                return ((0.0, 0.0), Vec::new());
            }
            entries.sort_by_key(|e| e.0);
            let mut merged: Vec<(u32, Vector3<f64>)> = Vec::with_capacity(entries.len());
            for (node, v) in entries {
                match merged.last_mut() {
                    Some(last) if last.0 == node => last.1 += v,
                    _ => merged.push((node, v)),
                }
            }
            for e in &mut merged {
                e.1 /= vol;
            }
            ((vk / 4.0, if vmu > 0.0 { vk / vmu } else { 0.0 }), merged)
        })
        .collect();
    let (weight, rows): (Vec<(f64, f64)>, Vec<_>) = rows.into_iter().unzip();
    let (weight, ratio) = weight.into_iter().unzip();
    (RankOneSum::new(weight, &rows, n), ratio)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Model, ModelOptions, Solid, TetFormulation};
    use bs_material::Material;
    use bs_mesh::structured::box_mesh;

    /// `K₀ v` against the central difference of the internal forces at the reference state,
    /// which is the definition of the linearisation (independent of how `K₀` is built).
    fn check(tet: TetFormulation, hexes: bool) {
        let mut mesh = box_mesh(3, 1.0, !hexes);
        for (i, p) in mesh.nodes.iter_mut().enumerate() {
            let t = i as f64;
            p.x += 0.03 * (1.7 * t).sin();
            p.y += 0.03 * (2.3 * t).cos() + 0.1 * p.x;
            p.z += 0.03 * (0.9 * t).sin();
        }
        let solid =
            Solid { material: Material::neo_hookean(3000.0, 0.45).unwrap(), density: 1000.0 };
        let model = Model::uniform(&mesh, solid, ModelOptions { tet, hourglass: 0.1 }).unwrap();
        let k = model.linear_stiffness();
        let n = model.node_count();
        let v: Vec<Vector3<f64>> = (0..n)
            .map(|i| {
                Vector3::new(
                    (i as f64 * 0.7).sin(),
                    (i as f64 * 1.3).cos(),
                    0.5 - (i % 3) as f64 * 0.4,
                )
            })
            .collect();
        let mut kv = vec![Vector3::zeros(); n];
        let mut s = k.scratch();
        k.mul(&v, &mut kv, &mut s);
        let h = 1e-6;
        let mut ws = model.workspace();
        let (mut fp, mut fm) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
        let up: Vec<_> = v.iter().map(|x| x * h).collect();
        let um: Vec<_> = v.iter().map(|x| -x * h).collect();
        model.internal_forces_into(&up, &mut ws, &mut fp).unwrap();
        model.internal_forces_into(&um, &mut ws, &mut fm).unwrap();
        let scale = kv.iter().fold(0.0f64, |m, x| m.max(x.amax()));
        for i in 0..n {
            let fd = (fp[i] - fm[i]) / (2.0 * h);
            assert!((fd - kv[i]).amax() <= 1e-6 * scale, "node {i}: {fd:?} vs {:?}", kv[i]);
        }
        // The diagonal blocks are those of the operator.
        for a in [0, n / 2, n - 1] {
            let mut col = [Vector3::zeros(); 3];
            for (c, out) in col.iter_mut().enumerate() {
                let mut e = vec![Vector3::zeros(); n];
                e[a][c] = 1.0;
                let mut y = vec![Vector3::zeros(); n];
                k.mul(&e, &mut y, &mut s);
                *out = y[a];
            }
            let d = k.diagonal(a);
            for c in 0..3 {
                assert!((d.column(c) - col[c]).amax() <= 1e-9 * scale);
            }
        }
    }

    #[test]
    fn t4_stiffness_is_the_linearised_force() {
        check(TetFormulation::T4, false);
    }

    #[test]
    fn t4anp_stiffness_is_the_linearised_force() {
        check(TetFormulation::T4Anp, false);
    }

    #[test]
    fn h8_stiffness_is_the_linearised_force() {
        check(TetFormulation::T4, true);
    }
}
