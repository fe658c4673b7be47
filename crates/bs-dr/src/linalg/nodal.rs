//! A symmetric matrix on nodal vectors made of two parts: an assembled block-sparse part and
//! an optional sum of rank-one nodal terms, `A = E + Cᵀ W C`. The linearised stiffness `K₀`
//! has this form (the T4ANP volumetric term is a rank-one sum that assembled would couple
//! every node with its two-ring); the preconditioner and the products only need the form.

use bs_mesh::Vector3;
use nalgebra::Matrix3;

use super::sparse::{BlockCsr, RankOneSum};

/// `A = E + Cᵀ W C`: the assembled part `E` and the rank-one terms, if any.
#[derive(Debug, Clone)]
pub struct NodalMatrix {
    /// The assembled block part.
    pub assembled: BlockCsr,
    /// The rank-one nodal terms, if any.
    pub nodal: Option<RankOneSum>,
    /// Per nodal term, how much stiffer it is than the assembled part around it (T4ANP:
    /// the volume averages `κ̄/μ̄` at the node); empty without nodal terms.
    pub ratio: Vec<f64>,
}

/// Scratch of [`NodalMatrix::mul`]: one value per rank-one term.
#[derive(Debug, Clone, Default)]
pub struct NodalScratch {
    terms: Vec<f64>,
}

impl NodalMatrix {
    /// Scratch buffers for [`mul`](Self::mul).
    pub fn scratch(&self) -> NodalScratch {
        NodalScratch { terms: vec![0.0; self.nodal.as_ref().map_or(0, RankOneSum::terms)] }
    }

    /// `y = A x`.
    pub fn mul(&self, x: &[Vector3<f64>], y: &mut [Vector3<f64>], s: &mut NodalScratch) {
        self.assembled.mul(x, y);
        if let Some(nodal) = &self.nodal {
            nodal.project_into(x, &mut s.terms);
            nodal.add_expand(&s.terms, y);
        }
    }

    /// The 3×3 diagonal block of node `a` (both parts).
    pub fn diagonal(&self, a: usize) -> Matrix3<f64> {
        let mut d = self.assembled.diagonal(a);
        if let Some(nodal) = &self.nodal {
            let (lo, hi) = (nodal.t_ptr[a] as usize, nodal.t_ptr[a + 1] as usize);
            for k in lo..hi {
                let c = nodal.t_val[k];
                d += c * c.transpose() * nodal.weight[nodal.t_col[k] as usize];
            }
        }
        d
    }
}
