//! Boundary conditions: fixed and prescribed displacement components, and dead nodal
//! forces (a body force's consistent load vector, `body.rs`); every component not
//! constrained here carries only its nodal force.

use bs_mesh::Vector3;

/// Errors defining [`Loads`].
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum LoadError {
    /// A node index beyond the mesh.
    #[error("node index {node} is out of range: the mesh has {count} nodes")]
    NodeOutOfRange {
        /// The node index.
        node: usize,
        /// Number of nodes.
        count: usize,
    },
    /// A component index other than 0, 1, 2.
    #[error("displacement component {0} is out of range: use 0 (x), 1 (y) or 2 (z)")]
    ComponentOutOfRange(usize),
    /// A non-finite prescribed value.
    #[error(
        "prescribed displacement of node {node} component {component} is {value}: must be finite"
    )]
    NonFinite {
        /// The node index.
        node: usize,
        /// The component.
        component: usize,
        /// The value.
        value: f64,
    },
    /// A nodal force vector of another length than the nodes, or with a non-finite value.
    #[error(
        "nodal forces: {got} values (or a non-finite one) for {count} nodes: give one finite \
         force per node"
    )]
    Forces {
        /// Values given.
        got: usize,
        /// Number of nodes.
        count: usize,
    },
}

/// Per-node, per-component displacement constraints. A constrained component follows the
/// 3-4-5 ramp [`ramp`] from 0 to its final value; "fixed" is a final value of 0. Dead nodal
/// forces (constant in direction and size, per unit of the model's force) act on every
/// node; at a constrained component they go into the reaction.
#[derive(Debug, Clone, PartialEq)]
pub struct Loads {
    constrained: Vec<[bool; 3]>,
    value: Vec<Vector3<f64>>,
    /// Dead nodal forces (empty: none).
    force: Vec<Vector3<f64>>,
}

/// Smooth 3-4-5 polynomial ramp `10τ³ − 15τ⁴ + 6τ⁵` for `τ ∈ [0, 1]` (clamped outside):
/// zero velocity and acceleration at both ends.
pub fn ramp(tau: f64) -> f64 {
    let t = tau.clamp(0.0, 1.0);
    t * t * t * (10.0 + t * (-15.0 + 6.0 * t))
}

impl Loads {
    /// No constraints on `node_count` nodes.
    pub fn new(node_count: usize) -> Self {
        Loads {
            constrained: vec![[false; 3]; node_count],
            value: vec![Vector3::zeros(); node_count],
            force: Vec::new(),
        }
    }

    /// Sets the dead nodal forces (one per node; replaces any set before).
    pub fn set_forces(&mut self, forces: Vec<Vector3<f64>>) -> Result<(), LoadError> {
        let count = self.constrained.len();
        if forces.len() != count || forces.iter().any(|f| !f.iter().all(|x| x.is_finite())) {
            return Err(LoadError::Forces { got: forces.len(), count });
        }
        self.force =
            if forces.iter().all(|f| *f == Vector3::zeros()) { Vec::new() } else { forces };
        Ok(())
    }

    /// The dead nodal forces (empty without any).
    pub fn forces(&self) -> &[Vector3<f64>] {
        &self.force
    }

    /// Whether any dead nodal force acts.
    pub fn has_forces(&self) -> bool {
        !self.force.is_empty()
    }

    /// `f ← f − factor · f_ext`: the residual convention of
    /// [`Model::internal_forces_into`](crate::Model::internal_forces_into) (internal minus
    /// external) with the dead forces at `factor` of their value.
    pub fn subtract_forces_into(&self, factor: f64, f: &mut [Vector3<f64>]) {
        if factor != 0.0 {
            f.iter_mut().zip(&self.force).for_each(|(fi, e)| *fi -= e * factor);
        }
    }

    fn check(&self, node: usize, component: usize) -> Result<(), LoadError> {
        if node >= self.constrained.len() {
            return Err(LoadError::NodeOutOfRange { node, count: self.constrained.len() });
        }
        if component > 2 {
            return Err(LoadError::ComponentOutOfRange(component));
        }
        Ok(())
    }

    /// Fixes one component of a node (final displacement 0).
    pub fn fix(&mut self, node: usize, component: usize) -> Result<(), LoadError> {
        self.prescribe(node, component, 0.0)
    }

    /// Fixes all three components of a node.
    pub fn fix_node(&mut self, node: usize) -> Result<(), LoadError> {
        self.prescribe_node(node, Vector3::zeros())
    }

    /// Prescribes the final displacement of one component of a node.
    pub fn prescribe(
        &mut self,
        node: usize,
        component: usize,
        value: f64,
    ) -> Result<(), LoadError> {
        self.check(node, component)?;
        if !value.is_finite() {
            return Err(LoadError::NonFinite { node, component, value });
        }
        self.constrained[node][component] = true;
        self.value[node][component] = value;
        Ok(())
    }

    /// Prescribes the final displacement vector of a node (all three components).
    pub fn prescribe_node(&mut self, node: usize, value: Vector3<f64>) -> Result<(), LoadError> {
        for k in 0..3 {
            self.prescribe(node, k, value[k])?;
        }
        Ok(())
    }

    /// Removes any constraint from one component.
    pub fn release(&mut self, node: usize, component: usize) -> Result<(), LoadError> {
        self.check(node, component)?;
        self.constrained[node][component] = false;
        self.value[node][component] = 0.0;
        Ok(())
    }

    /// The same constraints with every prescribed value and nodal force multiplied by
    /// `factor` (the loads at load fraction `factor` of a continuation).
    pub fn scaled(&self, factor: f64) -> Loads {
        Loads {
            constrained: self.constrained.clone(),
            value: self.value.iter().map(|v| v * factor).collect(),
            force: self.force.iter().map(|v| v * factor).collect(),
        }
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.constrained.len()
    }

    /// Whether a component is constrained.
    pub fn is_constrained(&self, node: usize, component: usize) -> bool {
        self.constrained[node][component]
    }

    /// Whether any component of a node is constrained.
    pub fn is_node_constrained(&self, node: usize) -> bool {
        self.constrained[node].iter().any(|&c| c)
    }

    /// Final prescribed value of a component (0 for free components).
    pub fn value(&self, node: usize, component: usize) -> f64 {
        self.value[node][component]
    }

    /// Largest final prescribed component magnitude.
    pub fn max_prescribed(&self) -> f64 {
        self.value.iter().flat_map(|v| v.iter()).fold(0.0f64, |a, &x| a.max(x.abs()))
    }

    /// Number of constrained components.
    pub fn constrained_count(&self) -> usize {
        self.constrained.iter().flatten().filter(|&&c| c).count()
    }

    /// Flat DOF indices (`3·node + component`) of the free and constrained components.
    pub(crate) fn split_dofs(&self) -> (Vec<usize>, Vec<usize>) {
        let mut free = Vec::new();
        let mut fixed = Vec::new();
        for (n, c) in self.constrained.iter().enumerate() {
            for k in 0..3 {
                if c[k] {
                    fixed.push(3 * n + k);
                } else {
                    free.push(3 * n + k);
                }
            }
        }
        (free, fixed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 3-4-5 ramp: 0 and 1 at the ends, ½ in the middle, zero slope at both ends.
    #[test]
    fn ramp_345() {
        assert_eq!(ramp(0.0), 0.0);
        assert_eq!(ramp(1.0), 1.0);
        assert_eq!(ramp(0.5), 0.5);
        assert_eq!(ramp(-1.0), 0.0);
        assert_eq!(ramp(2.0), 1.0);
        let h = 1e-6;
        assert!((ramp(h) - ramp(0.0)) / h < 1e-10);
        assert!((ramp(1.0) - ramp(1.0 - h)) / h < 1e-10);
        // d(τ) = 10τ³ − 15τ⁴ + 6τ⁵ at τ = 0.3.
        assert!((ramp(0.3) - (0.27 - 15.0 * 0.0081 + 6.0 * 0.00243)).abs() < 1e-15);
    }

    #[test]
    fn load_errors_are_typed() {
        let mut l = Loads::new(3);
        assert_eq!(l.fix(3, 0), Err(LoadError::NodeOutOfRange { node: 3, count: 3 }));
        assert_eq!(l.fix(0, 3), Err(LoadError::ComponentOutOfRange(3)));
        assert!(matches!(
            l.prescribe(1, 1, f64::NAN),
            Err(LoadError::NonFinite { node: 1, component: 1, .. })
        ));
        l.prescribe(2, 1, -0.5).unwrap();
        assert_eq!((l.max_prescribed(), l.constrained_count()), (0.5, 1));
        assert_eq!(
            l.set_forces(vec![Vector3::zeros(); 2]),
            Err(LoadError::Forces { got: 2, count: 3 })
        );
        let nan = vec![Vector3::new(f64::NAN, 0.0, 0.0); 3];
        assert_eq!(l.set_forces(nan), Err(LoadError::Forces { got: 3, count: 3 }));
    }

    #[test]
    fn dead_forces_enter_the_residual_scaled() {
        let mut l = Loads::new(2);
        assert!(!l.has_forces());
        l.set_forces(vec![Vector3::new(0.0, 0.0, -2.0), Vector3::new(1.0, 0.0, 0.0)]).unwrap();
        let mut f = vec![Vector3::new(0.0, 0.0, 1.0); 2];
        l.subtract_forces_into(0.5, &mut f);
        assert_eq!(f, vec![Vector3::new(0.0, 0.0, 2.0), Vector3::new(-0.5, 0.0, 1.0)]);
        assert_eq!(l.scaled(2.0).forces()[0], Vector3::new(0.0, 0.0, -4.0));
        l.set_forces(vec![Vector3::zeros(); 2]).unwrap();
        assert!(!l.has_forces());
    }
}
