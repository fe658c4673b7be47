//! The discretised model: the mesh's elements with their precomputed reference data
//! (`element`), assigned to solids, in the assembly layout (blocks of four, node → slot map;
//! `assembly`), with the per-element stiffness bounds of the stable time step (`mass.rs`
//! turns them into masses and critical steps). The public face of everything below it:
//! forces, workspaces, `K₀`.

use bs_mesh::{ElementKind, Mesh, Point3, Vector3};
use rayon::prelude::*;

use crate::assembly::elements::{ElementList, Elements};
use crate::assembly::stiffness::linear_stiffness;
use crate::assembly::{
    Inversion, ReferenceWorkspace, StepBound, StiffnessScratch, VolumetricScratch, Workspace,
};
use crate::element::bound::BoundModuli;
use crate::element::{Hex, Solid, Tet, TetFormulation};
use crate::linalg::nodal::NodalMatrix;
use crate::linalg::sparse::RankOneSum;

/// Element technology options. Hexahedra always use the H8 mean-strain (uniform strain)
/// formulation of Flanagan & Belytschko (1981) with stiffness hourglass control.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelOptions {
    /// Formulation of the tetrahedra (T4 or T4ANP).
    pub tet: TetFormulation,
    /// Dimensionless hourglass stiffness coefficient κ_hg of the H8 elements
    /// (Flanagan & Belytschko recommend 0.05–0.15). Default 0.1.
    pub hourglass: f64,
}

impl Default for ModelOptions {
    fn default() -> Self {
        ModelOptions { tet: TetFormulation::T4, hourglass: 0.1 }
    }
}

/// Errors building a [`Model`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// The mesh has no elements.
    #[error("the mesh has no elements: a model needs at least one T4 or H8 element")]
    Empty,
    /// The per-element material list has the wrong length.
    #[error(
        "material assignment has {got} entries but the mesh has {expected} elements: give one \
         solid index per element"
    )]
    AssignmentLength {
        /// Number of elements.
        expected: usize,
        /// Entries given.
        got: usize,
    },
    /// An element refers to a solid that does not exist.
    #[error(
        "element {element} (id {element_id}) is assigned solid {solid} but only {count} solids \
         are defined"
    )]
    UnknownSolid {
        /// Element index.
        element: usize,
        /// External element id.
        element_id: u64,
        /// Solid index given.
        solid: usize,
        /// Number of solids.
        count: usize,
    },
    /// A solid has a non-positive or non-finite density.
    #[error("solid {solid} has density {density}: the density must be finite and > 0")]
    InvalidDensity {
        /// Solid index.
        solid: usize,
        /// Density given.
        density: f64,
    },
    /// A node index is out of range.
    #[error(
        "element {element} (id {element_id}) refers to node index {node} but the mesh has \
         {count} nodes"
    )]
    NodeOutOfRange {
        /// Element index.
        element: usize,
        /// External element id.
        element_id: u64,
        /// The node index.
        node: usize,
        /// Number of nodes.
        count: usize,
    },
    /// An element is inverted or degenerate in the reference configuration.
    #[error(
        "element {element} (id {element_id}) is inverted or degenerate in the reference mesh \
         (Jacobian {jacobian:e}): fix the node order (tets: (1-0)x(2-0)·(3-0) > 0; hexes: \
         bottom 0-1-2-3 counter-clockwise seen from the top face 4-5-6-7) or remesh"
    )]
    InvertedElement {
        /// Element index.
        element: usize,
        /// External element id.
        element_id: u64,
        /// Signed volume (tets) or smallest Gauss-point Jacobian determinant (hexes).
        jacobian: f64,
    },
    /// The hourglass coefficient is out of range.
    #[error("hourglass coefficient {0} must be finite and >= 0 (typical: 0.05-0.15)")]
    InvalidHourglass(f64),
}

/// A Total Lagrangian model ready for the solvers.
#[derive(Debug, Clone)]
pub struct Model {
    pub(crate) reference: Vec<Point3<f64>>,
    pub(crate) node_ids: Vec<u64>,
    pub(crate) options: ModelOptions,
    /// Largest eigenvalue of each element's small-strain stiffness (mesh element order).
    pub(crate) stiffness_bound: Vec<f64>,
    /// The elements in assembly order, their blocks and the node → slot map.
    pub(crate) elements: Elements,
}

/// Reference coordinates of an element's nodes (indices checked by [`check_element`]).
fn corners<const N: usize>(mesh: &Mesh, nodes: &[usize]) -> [Point3<f64>; N] {
    std::array::from_fn(|a| mesh.nodes[nodes[a]])
}

/// Element `e` with solid index `solid` refers to an existing solid and to nodes in range.
fn check_element(
    mesh: &Mesh,
    e: usize,
    solid: usize,
    solids: usize,
    eid: u64,
) -> Result<(), ModelError> {
    if solid >= solids {
        return Err(ModelError::UnknownSolid { element: e, element_id: eid, solid, count: solids });
    }
    let nn = mesh.nodes.len();
    match mesh.elements[e].nodes().iter().find(|&&n| n >= nn) {
        Some(&node) => {
            Err(ModelError::NodeOutOfRange { element: e, element_id: eid, node, count: nn })
        }
        None => Ok(()),
    }
}

/// `λ_max` of every element's small-strain stiffness, in mesh order (each solid's `D^(1/2)`
/// computed once; the elements in parallel).
fn stiffness_bounds(
    solids: &[Solid],
    ne: usize,
    (tets, tet_elem): (&[Tet], &[u32]),
    (hexes, hex_elem): (&[Hex], &[u32]),
) -> Vec<f64> {
    let moduli = BoundModuli::of(solids);
    let tet_bounds: Vec<f64> =
        tets.par_iter().map(|t| t.stiffness_bound(&moduli[t.mat as usize])).collect();
    let hex_bounds: Vec<f64> =
        hexes.par_iter().map(|h| h.stiffness_bound(&moduli[h.mat as usize])).collect();
    let mut bound = vec![0.0; ne];
    for (&e, b) in tet_elem.iter().zip(tet_bounds).chain(hex_elem.iter().zip(hex_bounds)) {
        bound[e as usize] = b;
    }
    bound
}

/// The mesh has elements, one solid index each, and the options and solids are valid.
fn check_inputs(
    mesh: &Mesh,
    solids: &[Solid],
    element_solid: &[usize],
    options: &ModelOptions,
) -> Result<(), ModelError> {
    let ne = mesh.elements.len();
    if ne == 0 {
        return Err(ModelError::Empty);
    }
    if element_solid.len() != ne {
        return Err(ModelError::AssignmentLength { expected: ne, got: element_solid.len() });
    }
    if !(options.hourglass >= 0.0 && options.hourglass.is_finite()) {
        return Err(ModelError::InvalidHourglass(options.hourglass));
    }
    for (i, s) in solids.iter().enumerate() {
        if !(s.density > 0.0 && s.density.is_finite()) {
            return Err(ModelError::InvalidDensity { solid: i, density: s.density });
        }
    }
    Ok(())
}

impl Model {
    /// Builds a model in which every element uses `solid`.
    pub fn uniform(mesh: &Mesh, solid: Solid, options: ModelOptions) -> Result<Self, ModelError> {
        let assignment = vec![0; mesh.elements.len()];
        Self::new(mesh, &[solid], &assignment, options)
    }

    /// Builds a model: `element_solid[e]` is the index into `solids` of element `e`.
    ///
    /// Precomputes the reference shape-function gradients, volumes, hourglass matrices,
    /// per-element stiffness bounds and the assembly map. Errors name the element by index
    /// and external id.
    pub fn new(
        mesh: &Mesh,
        solids: &[Solid],
        element_solid: &[usize],
        options: ModelOptions,
    ) -> Result<Self, ModelError> {
        check_inputs(mesh, solids, element_solid, &options)?;
        let (ne, nn) = (mesh.elements.len(), mesh.nodes.len());
        let eid = |e: usize| mesh.element_ids.get(e).copied().unwrap_or(e as u64 + 1);
        let (mut tets, mut tet_elem, mut hexes, mut hex_elem) = (vec![], vec![], vec![], vec![]);
        for (e, elem) in mesh.elements.iter().enumerate() {
            let s = element_solid[e];
            check_element(mesh, e, s, solids.len(), eid(e))?;
            let el = solids[s].material.elastic();
            let inverted =
                |jacobian| ModelError::InvertedElement { element: e, element_id: eid(e), jacobian };
            let n = elem.nodes();
            match elem.kind() {
                ElementKind::Tet4 => {
                    let nodes = std::array::from_fn(|a| n[a] as u32);
                    let t = Tet::new(nodes, s as u32, &corners(mesh, n)).map_err(inverted)?;
                    tets.push(t);
                    tet_elem.push(e as u32);
                }
                ElementKind::Hex8 => {
                    let nodes = std::array::from_fn(|a| n[a] as u32);
                    let x = corners(mesh, n);
                    let h =
                        Hex::new(nodes, s as u32, &x, &el, options.hourglass).map_err(inverted)?;
                    hexes.push(h);
                    hex_elem.push(e as u32);
                }
            }
        }
        let stiffness_bound = stiffness_bounds(solids, ne, (&tets, &tet_elem), (&hexes, &hex_elem));
        // The assembly runs the tets in Morton order of their centroids (memory locality);
        // each keeps its mesh element index.
        let centroids: Vec<Point3<f64>> = tets
            .iter()
            .map(|t| {
                let c = t
                    .nodes
                    .iter()
                    .fold(Vector3::zeros(), |c, &n| c + mesh.nodes[n as usize].coords);
                Point3::from(c / 4.0)
            })
            .collect();
        let order = crate::assembly::order::morton_order(&centroids);
        let tets: Vec<Tet> = order.iter().map(|&i| tets[i as usize]).collect();
        let tet_elem: Vec<u32> = order.iter().map(|&i| tet_elem[i as usize]).collect();
        let list = ElementList {
            solids: solids.to_vec(),
            tet: options.tet,
            tets: (tets, tet_elem),
            hexes: (hexes, hex_elem),
            element_ids: (0..ne).map(eid).collect(),
        };
        Ok(Model {
            reference: mesh.nodes.clone(),
            node_ids: if mesh.node_ids.len() == nn {
                mesh.node_ids.clone()
            } else {
                (1..=nn as u64).collect()
            },
            options,
            stiffness_bound,
            elements: Elements::new(list, nn),
        })
    }

    /// Diagonal of the reference bounding box (0 without nodes).
    pub fn diagonal(&self) -> f64 {
        let pts = &self.reference;
        let Some(&first) = pts.first() else { return 0.0 };
        let (lo, hi) = pts.iter().fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        (hi - lo).norm()
    }
    /// The largest `α ≤ alpha_max` such that moving the displacements `u` by `α d` keeps
    /// every element's volume ratio at least `fraction` (in `[0, 1)`) of its value at `u`
    /// (for T4ANP: every nodal volume ratio, and each tet's own above 5 %), with the element
    /// that limits it; exact per element (a cubic in `α`, see `element::step`). An element
    /// already inverted at `u` gives 0.
    pub fn step_bound(
        &self,
        u: &[Vector3<f64>],
        d: &[Vector3<f64>],
        fraction: f64,
        alpha_max: f64,
    ) -> StepBound {
        self.elements.step_bound(u, d, fraction, alpha_max)
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.reference.len()
    }
    /// Number of elements.
    pub fn element_count(&self) -> usize {
        self.stiffness_bound.len()
    }
    /// Reference node coordinates.
    pub fn reference(&self) -> &[Point3<f64>] {
        &self.reference
    }
    /// External node ids.
    pub fn node_ids(&self) -> &[u64] {
        &self.node_ids
    }
    /// External element ids.
    pub fn element_ids(&self) -> &[u64] {
        &self.elements.element_ids
    }
    /// The options the model was built with.
    pub fn options(&self) -> ModelOptions {
        self.options
    }
    /// Number of (tetrahedra, hexahedra).
    pub fn counts(&self) -> (usize, usize) {
        (self.elements.tets.len(), self.elements.hexes.len())
    }

    /// Mean edge length over the element edges (tets: 6 edges, hexes: 12); 1 without edges.
    pub(crate) fn mean_edge(&self) -> f64 {
        let x = &self.reference;
        let mut sum = 0.0;
        let mut count = 0usize;
        for (_, e) in self.elements.iter() {
            for &[a, b] in e.kind().edges() {
                sum += (x[e.nodes[a] as usize] - x[e.nodes[b] as usize]).norm();
                count += 1;
            }
        }
        if count == 0 { 1.0 } else { sum / count as f64 }
    }

    /// `K₀`, the small-strain stiffness at the reference state (see
    /// [`crate::assembly::stiffness`]).
    pub(crate) fn linear_stiffness(&self) -> NodalMatrix {
        linear_stiffness(&self.elements)
    }

    /// The stiffness of [`linear_stiffness`](Self::linear_stiffness) on the configuration
    /// `x` written into `k` (a matrix it built: see
    /// [`crate::assembly::stiffness_at`]); `false` when an element is inverted at `x`.
    pub(crate) fn stiffness_at_into(
        &self,
        x: &[Point3<f64>],
        k: &mut NodalMatrix,
        scratch: &mut StiffnessScratch,
    ) -> bool {
        let hourglass = self.options.hourglass;
        crate::assembly::stiffness_at::stiffness_at_into(&self.elements, hourglass, x, k, scratch)
    }

    /// The T4ANP nodal volumetric term of `K₀` on the configuration `x`, written into `c`,
    /// and the 99th percentile of `|J − 1|` over materials with `κ/μ > above` (see
    /// [`crate::assembly::volumetric::volumetric_at`]).
    pub(crate) fn volumetric_at(
        &self,
        x: &[Point3<f64>],
        c: &mut RankOneSum,
        above: f64,
        scratch: &mut VolumetricScratch,
    ) -> Option<f64> {
        crate::assembly::volumetric::volumetric_at(&self.elements, x, c, above, scratch)
    }

    /// Scratch buffers sized for this model.
    pub fn workspace(&self) -> Workspace {
        self.elements.workspace()
    }

    /// Internal nodal forces `f_int(u)` (the negative of the residual for zero external
    /// load) into the caller-owned `forces` (one per node), using `ws` as scratch.
    /// Allocation-free; parallel over elements and nodes with rayon on the current thread
    /// pool; bit-identical for any number of threads.
    ///
    /// Returns the lowest-indexed inverted element if any element has `det F ≤ 0` (its forces
    /// are then set to zero and `forces` must not be used).
    pub fn internal_forces_into(
        &self,
        u: &[Vector3<f64>],
        ws: &mut Workspace,
        forces: &mut [Vector3<f64>],
    ) -> Result<(), Inversion> {
        self.elements.internal_forces_into(u, ws, forces)
    }

    /// Scratch buffers for [`Model::internal_forces_scalar_into`].
    #[doc(hidden)]
    pub fn reference_workspace(&self) -> ReferenceWorkspace {
        self.elements.reference_workspace()
    }

    /// The scalar reference kernels (one element at a time, three T4ANP passes), with the
    /// same contract as [`Model::internal_forces_into`]. For tests and the benchmark's
    /// baseline only.
    #[doc(hidden)]
    pub fn internal_forces_scalar_into(
        &self,
        u: &[Vector3<f64>],
        ws: &mut ReferenceWorkspace,
        forces: &mut [Vector3<f64>],
    ) -> Result<(), Inversion> {
        self.elements.internal_forces_scalar_into(u, ws, forces)
    }
}

#[cfg(test)]
mod tests {
    use bs_material::Material;
    use bs_mesh::Element;

    use super::*;
    use crate::tests::distorted_mesh;

    #[test]
    fn model_errors_name_the_element() {
        let mut mesh = distorted_mesh();
        mesh.element_ids = vec![7, 8, 9];
        let solid =
            Solid { material: Material::neo_hookean(3000.0, 0.4).unwrap(), density: 1000.0 };
        let opts = ModelOptions::default();
        assert_eq!(
            Model::new(&mesh, &[solid], &[0, 0], opts).unwrap_err(),
            ModelError::AssignmentLength { expected: 3, got: 2 }
        );
        assert_eq!(
            Model::new(&mesh, &[solid], &[0, 1, 0], opts).unwrap_err(),
            ModelError::UnknownSolid { element: 1, element_id: 8, solid: 1, count: 1 }
        );
        let bad = Solid { density: 0.0, ..solid };
        assert_eq!(
            Model::new(&mesh, &[bad], &[0, 0, 0], opts).unwrap_err(),
            ModelError::InvalidDensity { solid: 0, density: 0.0 }
        );
        let mut m2 = mesh.clone();
        m2.elements[2] = Element::tet4([5, 6, 7, 99]);
        assert_eq!(
            Model::uniform(&m2, solid, opts).unwrap_err(),
            ModelError::NodeOutOfRange { element: 2, element_id: 9, node: 99, count: 9 }
        );
        // A hex with swapped top and bottom faces is inverted.
        let mut m3 = mesh.clone();
        m3.elements[0] = Element::hex8([4, 5, 6, 7, 0, 1, 2, 3]);
        assert!(matches!(
            Model::uniform(&m3, solid, opts).unwrap_err(),
            ModelError::InvertedElement { element: 0, element_id: 7, .. }
        ));
        assert!(matches!(
            Model::uniform(&mesh, solid, ModelOptions { hourglass: -1.0, ..opts }),
            Err(ModelError::InvalidHourglass(_))
        ));
    }
}
