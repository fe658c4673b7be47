//! The linear tetrahedron: reference volume and constant shape-function gradients
//! `∂N_a/∂X` (the rows of the inverse of the edge matrix; `g_0 = −(g_1 + g_2 + g_3)`).

use bs_mesh::Point3;

use super::view::ElementView;

/// Precomputed data of one tetrahedron.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tet {
    /// Node indices.
    pub nodes: [u32; 4],
    /// Index of its [`Solid`](super::Solid).
    pub mat: u32,
    /// Reference volume.
    pub vol: f64,
    /// Reference shape-function gradients ∂N_a/∂X.
    pub g: [[f64; 3]; 4],
    /// T4ANP: the nodal averaging group of each corner (its node, or another group where
    /// the node also belongs to tets of another solid: see `assembly::elements`).
    pub anp: [u32; 4],
}

impl Tet {
    /// The tetrahedron with nodes `nodes` at `x` and solid `mat`; `Err(V)` with its signed
    /// volume `V` when it is inverted, degenerate (`V ≤ 10⁻¹² L³`, `L` its longest edge from
    /// node 0) or not a number.
    pub(crate) fn new(nodes: [u32; 4], mat: u32, x: &[Point3<f64>; 4]) -> Result<Tet, f64> {
        let (vol, g) = tet_gradients(x);
        let scale = (x[1] - x[0]).norm().max((x[2] - x[0]).norm()).max((x[3] - x[0]).norm());
        if vol.is_nan() || vol <= 1e-12 * scale * scale * scale {
            return Err(vol);
        }
        Ok(Tet { nodes, mat, vol, g, anp: nodes })
    }

    /// The element as every per-element loop sees it.
    pub(crate) fn view(&self) -> ElementView<'_> {
        ElementView {
            nodes: &self.nodes,
            g: &self.g,
            vol: self.vol,
            mat: self.mat as usize,
            hg: None,
        }
    }
}

/// Volume and shape-function gradients of the tetrahedron `x`.
fn tet_gradients(x: &[Point3<f64>; 4]) -> (f64, [[f64; 3]; 4]) {
    let e1 = x[1] - x[0];
    let e2 = x[2] - x[0];
    let e3 = x[3] - x[0];
    let det = e1.cross(&e2).dot(&e3);
    let vol = det / 6.0;
    // Rows of the inverse of [e1 e2 e3] (columns) are the gradients of N1, N2, N3.
    let m = nalgebra::Matrix3::from_columns(&[e1, e2, e3]);
    let inv = m.try_inverse().unwrap_or_else(nalgebra::Matrix3::zeros);
    let mut g = [[0.0; 3]; 4];
    for a in 1..4 {
        for k in 0..3 {
            g[a][k] = inv[(a - 1, k)];
        }
    }
    for k in 0..3 {
        g[0][k] = -(g[1][k] + g[2][k] + g[3][k]);
    }
    (vol, g)
}
