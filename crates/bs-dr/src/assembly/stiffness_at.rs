//! The small-strain stiffness of [`super::stiffness`] moved to another configuration in
//! place: the element gradients, volumes and hexahedral hourglass matrices at `X + u`, the
//! reference moduli, written into a matrix of the same pattern. It is what the
//! preconditioner follows the state with (`nk/refresh.rs`): about the cost of a few force
//! evaluations, where building the matrix anew (pattern, slot maps) costs several times
//! more.

use bs_mesh::Point3;
use rayon::prelude::*;

use super::elements::Elements;
use super::stiffness::assemble_rows;
use super::volumetric::{VolumetricScratch, fill_moved, move_tets};
use crate::element::{Hex, Tet};
use crate::linalg::nodal::NodalMatrix;

/// Caller-owned buffers of [`stiffness_at_into`]: the elements on the configuration.
#[derive(Debug, Default)]
pub struct StiffnessScratch {
    tets: Vec<Tet>,
    hexes: Vec<Hex>,
    volumetric: VolumetricScratch,
}

/// The stiffness of `elements` with the nodes at `x` written into `k` (a matrix built by
/// `linear_stiffness` of the same elements: pattern kept, values replaced; the T4ANP nodal
/// term moved too, its stiffness ratios kept). `false`, `k` partly written, when an element
/// is inverted or flat at `x`.
pub(crate) fn stiffness_at_into(
    elements: &Elements,
    hourglass: f64,
    x: &[Point3<f64>],
    k: &mut NodalMatrix,
    s: &mut StiffnessScratch,
) -> bool {
    if !move_tets(elements, x, &mut s.tets) || !move_hexes(elements, hourglass, x, &mut s.hexes) {
        return false;
    }
    assemble_rows(elements, &s.tets, &s.hexes, &mut k.assembled);
    if let Some(c) = k.nodal.as_mut() {
        fill_moved(elements, &s.tets, c, &mut s.volumetric);
    }
    true
}

/// The hexahedra of `elements` with their mean gradients, volumes and hourglass matrices at
/// `x` written into `hexes`; `false` when one is inverted there.
fn move_hexes(
    elements: &Elements,
    hourglass: f64,
    x: &[Point3<f64>],
    hexes: &mut Vec<Hex>,
) -> bool {
    hexes.clear();
    hexes.extend_from_slice(&elements.hexes);
    hexes.par_iter_mut().with_min_len(64).all(|h| {
        let corners = h.nodes.map(|a| x[a as usize]);
        let el = elements.solids[h.mat as usize].material.elastic();
        Hex::new(h.nodes, h.mat, &corners, &el, hourglass).map(|moved| *h = moved).is_ok()
    })
}

#[cfg(test)]
mod tests {
    use bs_material::Material;
    use bs_mesh::Vector3;
    use bs_mesh::structured::box_mesh;

    use super::StiffnessScratch;
    use crate::{Model, ModelOptions, Solid, TetFormulation};

    /// A smooth deformation changing volumes by up to about 10 %.
    fn deformed(model: &Model) -> Vec<bs_mesh::Point3<f64>> {
        model
            .reference()
            .iter()
            .map(|p| p + Vector3::new(0.1 * p.x * p.y, 0.05 * (3.0 * p.z).sin(), -0.08 * p.x))
            .collect()
    }

    /// The stiffness moved in place against `K₀` of a model meshed on the moved nodes (an
    /// independent construction), for tetrahedra (T4, T4ANP) and hexahedra.
    #[test]
    fn the_stiffness_moved_in_place_is_k0_of_the_moved_mesh() {
        for (tets, tet) in
            [(true, TetFormulation::T4), (true, TetFormulation::T4Anp), (false, TetFormulation::T4)]
        {
            let mesh = box_mesh(3, 1.0, tets);
            let solid =
                Solid { material: Material::neo_hookean(3000.0, 0.45).unwrap(), density: 1000.0 };
            let opts = ModelOptions { tet, hourglass: 0.1 };
            let model = Model::uniform(&mesh, solid, opts).unwrap();
            let x = deformed(&model);
            let mut k = model.linear_stiffness();
            let mut s = StiffnessScratch::default();
            // Twice, so that the second call reuses the scratch.
            assert!(model.stiffness_at_into(&x, &mut k, &mut s));
            assert!(model.stiffness_at_into(&x, &mut k, &mut s));
            let mut moved_mesh = mesh.clone();
            moved_mesh.nodes.clone_from(&x);
            let expect = Model::uniform(&moved_mesh, solid, opts).unwrap().linear_stiffness();
            let scale = expect.assembled.val.iter().fold(0.0f64, |m, b| m.max(b.amax()));
            assert_eq!(k.assembled.col, expect.assembled.col);
            for (a, b) in k.assembled.val.iter().zip(&expect.assembled.val) {
                assert!((a - b).amax() <= 1e-12 * scale, "{a} vs {b}");
            }
            if let (Some(kn), Some(en)) = (&k.nodal, &expect.nodal) {
                for (a, b) in kn.weight.iter().zip(&en.weight) {
                    assert!((a - b).abs() <= 1e-12 * b.abs());
                }
                for (a, b) in kn.c_val.iter().zip(&en.c_val) {
                    assert!((a - b).amax() <= 1e-9 * b.amax().max(1.0));
                }
            }
            assert_eq!(k.nodal.is_some(), tet == TetFormulation::T4Anp && tets);
        }
    }

    #[test]
    fn an_inverted_element_is_refused() {
        let mesh = box_mesh(2, 1.0, true);
        let solid =
            Solid { material: Material::neo_hookean(3000.0, 0.45).unwrap(), density: 1000.0 };
        let model = Model::uniform(&mesh, solid, ModelOptions::default()).unwrap();
        let mut x = model.reference().to_vec();
        x.iter_mut().for_each(|p| p.z = -p.z);
        let mut k = model.linear_stiffness();
        assert!(!model.stiffness_at_into(&x, &mut k, &mut StiffnessScratch::default()));
    }
}
