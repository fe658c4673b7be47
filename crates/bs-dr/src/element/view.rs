//! One view of any element for the loops that treat tetrahedra and hexahedra alike (masses,
//! stiffness patterns, tangents, post-processing): its nodes, gradients, volume, solid and,
//! for a hexahedron, its hourglass matrix.

use bs_mesh::{ElementKind, Vector3};
use nalgebra::Matrix3;

use super::kinematics::deformation_gradient_of;

/// An element as the generic loops see it (tets: 4 nodes, no hourglass matrix; hexes: 8).
#[derive(Debug, Clone, Copy)]
pub(crate) struct ElementView<'a> {
    /// Node indices.
    pub nodes: &'a [u32],
    /// Reference (mean) shape-function gradients, one per node.
    pub g: &'a [[f64; 3]],
    /// Reference volume.
    pub vol: f64,
    /// Index of its solid.
    pub mat: usize,
    /// The hourglass stiffness matrix of a hexahedron.
    pub hg: Option<&'a [[f64; 8]; 8]>,
}

impl ElementView<'_> {
    /// Number of nodes.
    pub(crate) fn len(&self) -> usize {
        self.nodes.len()
    }

    /// T4 or H8.
    pub(crate) fn kind(&self) -> ElementKind {
        if self.nodes.len() == 4 { ElementKind::Tet4 } else { ElementKind::Hex8 }
    }

    /// `F = I + Σ_a u_a ⊗ g_a` for the nodal displacements `u`.
    pub(crate) fn deformation_gradient(&self, u: &[Vector3<f64>]) -> Matrix3<f64> {
        deformation_gradient_of(u, self.nodes, self.g)
    }
}
