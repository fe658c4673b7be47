//! The deformation gradient of an element from its nodal displacements and reference
//! gradients, `F = I + Σ_a u_a ⊗ g_a`, and its determinant: what every kernel, the tangent
//! and the post-processing evaluate first.

use bs_mesh::Vector3;
use nalgebra::Matrix3;

/// `F = I + Σ_a u_a ⊗ g_a` (row i = displacement component, column j = reference direction).
#[inline(always)]
pub(crate) fn deformation_gradient<const N: usize>(
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

/// [`deformation_gradient`] of an element with any number of nodes (`nodes.len() ==
/// g.len()`): the same sums in the same order (the kernels keep the fixed-size form, which
/// the compiler unrolls).
#[inline(always)]
pub(crate) fn deformation_gradient_of(
    u: &[Vector3<f64>],
    nodes: &[u32],
    g: &[[f64; 3]],
) -> Matrix3<f64> {
    let mut f = Matrix3::identity();
    for (a, &n) in nodes.iter().enumerate() {
        let ua = &u[n as usize];
        for j in 0..3 {
            for i in 0..3 {
                f[(i, j)] += ua[i] * g[a][j];
            }
        }
    }
    f
}

/// `det F` by the first-row expansion.
#[inline(always)]
pub(crate) fn det3(f: &Matrix3<f64>) -> f64 {
    f[(0, 0)] * (f[(1, 1)] * f[(2, 2)] - f[(1, 2)] * f[(2, 1)])
        - f[(0, 1)] * (f[(1, 0)] * f[(2, 2)] - f[(1, 2)] * f[(2, 0)])
        + f[(0, 2)] * (f[(1, 0)] * f[(2, 1)] - f[(1, 1)] * f[(2, 0)])
}
