//! Nodal constraints: the orthogonal projector `Π` onto the directions each node may move in
//! (prescribed components, contact normals), and the inverse of a projected diagonal block.

use bs_mesh::Vector3;
use nalgebra::Matrix3;
use rayon::prelude::*;

/// Nodal constraints: the orthogonal projector onto the admissible directions of each node.
#[derive(Debug, Clone)]
pub struct Projector {
    /// `Π_a`, identity for unconstrained nodes.
    pub matrix: Vec<Matrix3<f64>>,
    /// Whether node `a` has any constraint.
    pub constrained: Vec<bool>,
}

impl Projector {
    /// No constraint on `n` nodes.
    pub fn free(n: usize) -> Self {
        Projector { matrix: vec![Matrix3::identity(); n], constrained: vec![false; n] }
    }

    /// Constrains node `a` along the orthonormal directions `dirs` (replacing what it had).
    pub fn set(&mut self, a: usize, dirs: &[Vector3<f64>]) {
        let mut m = Matrix3::identity();
        for d in dirs {
            m -= d * d.transpose();
        }
        self.matrix[a] = m;
        self.constrained[a] = !dirs.is_empty();
    }

    /// `x ← Π x`.
    pub fn apply(&self, x: &mut [Vector3<f64>]) {
        x.par_iter_mut()
            .zip(self.matrix.par_iter())
            .zip(self.constrained.par_iter())
            .with_min_len(1024)
            .for_each(|((v, m), &c)| {
                if c {
                    *v = m * *v;
                }
            });
    }
}

/// Inverse of `Π K Π` on the range of `Π`, zero on its complement.
pub(crate) fn projected_inverse(k: &Matrix3<f64>, pi: &Matrix3<f64>) -> Matrix3<f64> {
    let id = Matrix3::identity();
    let m = pi * k * pi + (id - pi);
    match m.try_inverse() {
        Some(inv) => pi * inv * pi,
        None => Matrix3::zeros(),
    }
}
