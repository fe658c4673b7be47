//! The session's prescribed boundaries resolved once, when the session is made: per
//! `[[boundary]]` with a node set that moves, its nodes, the components it holds and its
//! distance limit ([`SetLoad`]). An update's values are then written straight into the
//! per-node prescribed values — no copy of the scene, no second pass over its tables, no
//! file: a uniform displacement on the components the boundary holds, one displacement per
//! node, or each node's closest point on a surface sent in memory (`boundaries.rs` finds a
//! set by name for the session).

use bs_mesh::Vector3;

use super::update::BoundaryValues;
use crate::SceneError;
use crate::boundary::{Prescribed, select_nodes};
use crate::prepare::Prepared;
use crate::scene::Boundary;

/// A `[[boundary]]` an update may give new values, resolved once.
#[derive(Debug, Clone)]
pub(crate) struct SetLoad {
    /// Its position among the scene's `[[boundary]]` tables.
    pub boundary: usize,
    /// Its node set.
    pub name: String,
    /// The set's nodes (indices, in the set's order).
    pub nodes: Vec<usize>,
    /// The components it prescribes.
    pub components: [bool; 3],
    /// Largest node-to-surface distance of a surface update, mesh units.
    pub max_distance: f64,
}

/// Whether the boundary prescribes (possibly non-zero) displacements rather than fixing.
pub(crate) fn moves(b: &Boundary) -> bool {
    b.displacement.is_some()
        || b.displacement_file.is_some()
        || b.surface.is_some()
        || b.landmarks.is_some()
}

/// Every moving `[[boundary]]` with a node set of `p`'s scene, resolved.
pub(crate) fn resolve_sets(p: &Prepared) -> Result<Vec<SetLoad>, SceneError> {
    let default_distance = crate::scene::DEFAULT_MAX_DISTANCE_MM * 1e-3 / p.scene.units.metres();
    let mut out = Vec::new();
    for (i, b) in p.scene.boundaries.iter().enumerate() {
        let Some(name) = b.nset.as_ref().filter(|_| moves(b)) else { continue };
        let (_, nodes) = select_nodes(&p.path, &p.scene, &p.mesh, i, b)?;
        let components = match &b.displacement {
            Some(d) => d.components().map(|c| c.is_some()),
            None => [true; 3],
        };
        let max_distance = b.max_distance.unwrap_or(default_distance);
        out.push(SetLoad { boundary: i, name: name.clone(), nodes, components, max_distance });
    }
    Ok(out)
}

impl SetLoad {
    fn err(&self, p: &Prepared, message: String) -> SceneError {
        SceneError::Set {
            scene: p.path.clone(),
            key: "update".into(),
            set: self.name.clone(),
            message,
        }
    }

    /// Writes `values` into `prescribed` for this set's nodes.
    pub fn write(
        &self,
        p: &Prepared,
        values: &BoundaryValues,
        prescribed: &mut Prescribed,
    ) -> Result<(), SceneError> {
        match values {
            BoundaryValues::Uniform(v) => {
                self.check_uniform(p, v)?;
                for &n in &self.nodes {
                    self.put(prescribed, n, v, self.components);
                }
            }
            BoundaryValues::PerNode(v) => {
                if v.len() != self.nodes.len() {
                    return Err(self.err(p, format!(
                        "{} displacements for {} nodes; give one (dx, dy, dz) per node of the set",
                        v.len(),
                        self.nodes.len()
                    )));
                }
                for (k, (&n, d)) in self.nodes.iter().zip(v).enumerate() {
                    if !d.iter().all(|x| x.is_finite()) {
                        let id = p.mesh.node_ids[n];
                        return Err(self.err(p, format!("row {k} (node {id}) is not finite")));
                    }
                    self.put(prescribed, n, d, self.components);
                }
            }
            BoundaryValues::Surface(s) => {
                let key = format!("[[boundary]] #{} surface", self.boundary + 1);
                let moves = crate::loads::surface_moves(
                    &p.path,
                    key,
                    "the surface sent",
                    s,
                    &p.mesh,
                    &self.nodes,
                    self.max_distance,
                )?;
                for (&n, d) in self.nodes.iter().zip(&moves) {
                    self.put(prescribed, n, d, [true; 3]);
                }
            }
        }
        Ok(())
    }

    fn put(&self, prescribed: &mut Prescribed, n: usize, v: &Vector3<f64>, components: [bool; 3]) {
        for c in (0..3).filter(|&c| components[c]) {
            prescribed[n][c] = Some(v[c]);
        }
    }

    /// Refuses a non-finite component, and a non-zero one the boundary leaves free.
    fn check_uniform(&self, p: &Prepared, v: &Vector3<f64>) -> Result<(), SceneError> {
        for c in 0..3 {
            let x = v[c];
            let why = if !x.is_finite() {
                "a displacement must be a finite number"
            } else if !self.components[c] && x != 0.0 {
                "the boundary leaves this component free; give 0 for it"
            } else {
                continue;
            };
            return Err(self.err(p, format!("component {} = {x}: {why}", ["x", "y", "z"][c])));
        }
        Ok(())
    }
}
