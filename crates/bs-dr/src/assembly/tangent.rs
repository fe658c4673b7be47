//! The consistent tangent of one element in the formulation of its force kernel, for the
//! Newton–Raphson reference: `K_ab = V [ (g_a·S g_b) I + B_aᵀ ℂ B_b ] (+ K_hg)`, with `S` and
//! `ℂ` the law's second Piola–Kirchhoff stress and material tangent at `C = FᵀF`.

use bs_material::Material;
use bs_mesh::Vector3;

use crate::element::ElementView;

/// Consistent tangent of one element (3n×3n, row-major into `k`), in the same
/// formulation as the force kernels: `K_ab = V [ (g_a·S g_b) I + B_aᵀ ℂ B_b ] (+ K_hg)`.
/// Returns false if the element is inverted (`J ≤ 0` or not finite).
pub(crate) fn element_tangent(
    material: &Material,
    e: &ElementView<'_>,
    u: &[Vector3<f64>],
    k: &mut [f64],
) -> bool {
    let nn = e.len();
    let f = e.deformation_gradient(u);
    let j = f.determinant();
    if !(j > 0.0 && j.is_finite()) {
        return false;
    }
    let c = f.transpose() * f;
    let (s, d) = material.tangent_cj(&c, j);
    // B_a (6×3): row (I,J) normal: F_kI g_I; shear: F_kI g_J + F_kJ g_I.
    let mut b = [nalgebra::SMatrix::<f64, 6, 3>::zeros(); 8];
    for a in 0..nn {
        let g = e.g[a];
        for (r, &(ii, jj)) in bs_material::VOIGT.iter().enumerate() {
            for kk in 0..3 {
                b[a][(r, kk)] = if ii == jj {
                    f[(kk, ii)] * g[ii]
                } else {
                    f[(kk, ii)] * g[jj] + f[(kk, jj)] * g[ii]
                };
            }
        }
    }
    let n3 = 3 * nn;
    for a in 0..nn {
        for bb in 0..nn {
            let geo = {
                let ga = nalgebra::Vector3::from(e.g[a]);
                let gb = nalgebra::Vector3::from(e.g[bb]);
                ga.dot(&(s * gb))
            };
            let mat = b[a].transpose() * d * b[bb];
            for i in 0..3 {
                for jx in 0..3 {
                    let mut v = e.vol * mat[(i, jx)];
                    if i == jx {
                        v += e.vol * geo;
                        if let Some(hg) = e.hg {
                            v += hg[a][bb];
                        }
                    }
                    k[(3 * a + i) * n3 + 3 * bb + jx] = v;
                }
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tests::model;

    /// The Newton element tangent equals the central finite difference of the kernel forces
    /// (h = 1e-7 on displacements of O(0.1): truncation ~1e-14, round-off ~1e-16·f/1e-7 ~ 1e-9
    /// relative; tolerance 1e-6 of the largest entry).
    #[test]
    fn element_tangent_matches_finite_difference_of_forces() {
        let m = model();
        let n = m.node_count();
        let u: Vec<Vector3<f64>> = (0..n)
            .map(|i| {
                Vector3::new(
                    0.05 * (i as f64).sin(),
                    0.04 * (1.3 * i as f64).cos(),
                    -0.03 * (0.7 * i as f64).sin(),
                )
            })
            .collect();
        let mut ws = m.workspace();
        let mut fp = vec![Vector3::zeros(); n];
        let mut fm = fp.clone();
        // Global K·v from element tangents vs FD of global forces.
        for probe in 0..3 * n {
            let (node, comp) = (probe / 3, probe % 3);
            let mut kv = vec![Vector3::<f64>::zeros(); n];
            let mut ke = vec![0.0; 24 * 24];
            for (_, e) in m.elements.iter() {
                let nn = e.nodes.len();
                let n3 = 3 * nn;
                let material = &m.elements.solids[e.mat].material;
                assert!(element_tangent(material, &e, &u, &mut ke[..n3 * n3]));
                if let Some(b) = e.nodes.iter().position(|&x| x as usize == node) {
                    for a in 0..nn {
                        for i in 0..3 {
                            kv[e.nodes[a] as usize][i] += ke[(3 * a + i) * n3 + 3 * b + comp];
                        }
                    }
                }
            }
            let h = 1e-7;
            let mut up = u.clone();
            up[node][comp] += h;
            let mut um = u.clone();
            um[node][comp] -= h;
            m.internal_forces_into(&up, &mut ws, &mut fp).unwrap();
            m.internal_forces_into(&um, &mut ws, &mut fm).unwrap();
            let scale = kv.iter().fold(0.0f64, |s, v| s.max(v.amax()));
            for a in 0..n {
                let fd = (fp[a] - fm[a]) / (2.0 * h);
                assert!(
                    (fd - kv[a]).amax() <= 1e-6 * scale,
                    "dof {probe} node {a}: {fd} vs {}",
                    kv[a]
                );
            }
        }
    }
}
