//! The step bound of [`crate::element::step`] over every element of a model: the smallest
//! (ties to the lowest element index, so the same for any thread count). For T4ANP the
//! volume ratio that sets the volumetric stress is the nodal one, `Σ V_e J_e / Σ V_e` over the
//! tets around a node (a cubic in `α` too), which is kept instead; each tet's own ratio only
//! has to stay above 5 % of its value (so that it does not invert).

use bs_mesh::Vector3;
use rayon::prelude::*;

use super::elements::Elements;
use crate::element::TetFormulation;
use crate::element::step::{cubic_bound, element_bound, element_cubic, first_crossing};

/// The result of `Model::step_bound`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepBound {
    /// The largest admissible step, at most the `alpha_max` asked for.
    pub alpha: f64,
    /// The element (mesh order) whose volume ratio limits the step, when one does.
    pub element: Option<usize>,
}

/// The fraction of its current value that an element volume ratio not itself a material
/// measure (a T4ANP tetrahedron's own `J`, whose volumetric stress comes from the nodal
/// average) must keep: only so that it does not invert.
const ELEMENT_FLOOR: f64 = 0.05;

impl Elements {
    /// The largest `α ≤ alpha_max` such that moving the displacements `u` by `α d` keeps
    /// every element's volume ratio at least `fraction` (in `[0, 1)`) of its value at `u`
    /// (see the module documentation). For T4ANP tetrahedra the ratio kept is the nodal one
    /// (the volume-weighted average of the element ratios around a node, a cubic in `α`
    /// too), which sets their volumetric stress; each element's own ratio only has to stay
    /// above 5 % of its value. An element already inverted at `u` gives 0.
    pub(crate) fn step_bound(
        &self,
        u: &[Vector3<f64>],
        d: &[Vector3<f64>],
        fraction: f64,
        alpha_max: f64,
    ) -> StepBound {
        let anp = self.tet == TetFormulation::T4Anp;
        let none = || (alpha_max, u32::MAX);
        // T4ANP: each tet's cubic once, for its own bound and the nodal sums.
        let cubics: Option<Vec<[f64; 4]>> = anp.then(|| {
            self.tets
                .par_iter()
                .with_min_len(1024)
                .map(|t| element_cubic(u, d, &t.nodes, &t.g))
                .collect()
        });
        let tets = match &cubics {
            Some(c) => c
                .par_iter()
                .zip(self.tet_elem.par_iter())
                .with_min_len(1024)
                .map(|(c, &e)| (cubic_bound(*c, ELEMENT_FLOOR, alpha_max), e))
                .reduce(none, min_pair),
            None => self
                .tets
                .par_iter()
                .zip(self.tet_elem.par_iter())
                .with_min_len(1024)
                .map(|(t, &e)| (element_bound(u, d, &t.nodes, &t.g, fraction, alpha_max), e))
                .reduce(none, min_pair),
        };
        let hexes = self
            .hexes
            .par_iter()
            .zip(self.hex_elem.par_iter())
            .with_min_len(256)
            .map(|(h, &e)| (element_bound(u, d, &h.nodes, &h.g, fraction, alpha_max), e))
            .reduce(none, min_pair);
        let (mut alpha, mut e) = min_pair(tets, hexes);
        if let Some(cubics) = cubics.filter(|c| !c.is_empty()) {
            let (a, n) = self.nodal_bound(&cubics, fraction, alpha);
            if a < alpha {
                alpha = a;
                e = self.tet_elem[self.first_tet_of(n)];
            }
        }
        StepBound { alpha, element: (alpha < alpha_max).then_some(e as usize) }
    }

    /// The smallest bound over nodes of the nodal volume ratio `Σ V_e J_e / Σ V_e` (tets
    /// around the node, whose cubics are `cubics`), and the node.
    fn nodal_bound(&self, cubics: &[[f64; 4]], fraction: f64, alpha_max: f64) -> (f64, usize) {
        // Summed per node in tet order: the same sums for any thread count.
        let mut nodal = vec![[0.0f64; 4]; self.anp_inv_vol.len()];
        for (t, c) in self.tets.iter().zip(cubics) {
            let c = c.map(|c| c * t.vol);
            for &g in &t.anp {
                for k in 0..4 {
                    nodal[g as usize][k] += c[k];
                }
            }
        }
        let (a, n) = nodal
            .par_iter()
            .enumerate()
            .with_min_len(1024)
            .filter(|(_, c)| c[0] != 0.0)
            .map(|(n, c)| {
                let a =
                    if c[0] > 0.0 { first_crossing(*c, fraction * c[0], alpha_max) } else { 0.0 };
                (a, n as u32)
            })
            .reduce(|| (alpha_max, u32::MAX), min_pair);
        (a, n as usize)
    }

    /// The lowest-index tet of averaging group `g` (for one solid: of node `g`).
    fn first_tet_of(&self, g: usize) -> usize {
        self.tets.iter().position(|t| t.anp.contains(&(g as u32))).unwrap_or(0)
    }
}

/// The smaller bound; ties to the lower index (the same for any thread count).
fn min_pair(a: (f64, u32), b: (f64, u32)) -> (f64, u32) {
    if a.0 < b.0 || (a.0 == b.0 && a.1 < b.1) { a } else { b }
}

#[cfg(test)]
mod tests {
    use crate::{Model, ModelOptions, Solid, StepBound};
    use bs_material::Material;
    use bs_mesh::Vector3;

    /// On a model: pushing one tet's apex through its base is bounded where its volume
    /// reaches the fraction, and the limiting element is named.
    #[test]
    fn a_model_step_is_bounded_by_the_element_it_would_crush() {
        let mesh = crate::tests::unit_tet();
        let solid = Solid { material: Material::neo_hookean(3000.0, 0.4).unwrap(), density: 1.0 };
        let m = Model::uniform(&mesh, solid, ModelOptions::default()).unwrap();
        let u = vec![Vector3::zeros(); 4];
        let mut d = u.clone();
        d[3] = Vector3::new(0.0, 0.0, -2.0); // J(α) = 1 − 2α
        let b = m.step_bound(&u, &d, 0.5, 1.0);
        assert!((b.alpha - 0.25).abs() < 1e-15, "{b:?}");
        assert_eq!(b.element, Some(0));
        let free = m.step_bound(&u, &d, 0.5, 0.1);
        assert_eq!(free, StepBound { alpha: 0.1, element: None });
    }
}
