//! The discretised model: elements with precomputed reference shape-function derivatives,
//! material assignment, hourglass matrices, stiffness bounds for the stable time step and the
//! node → element-slot map used for deterministic force assembly.

use bs_material::{Elastic, Material, Tangent};
use bs_mesh::{ElementKind, Mesh, Point3};
use nalgebra::{SMatrix, SymmetricEigen};

use crate::kernels::layout::{HexBlock, TetBlock, hex_blocks, tet_blocks, tet_slot_counts};

/// Formulation used for linear tetrahedra.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TetFormulation {
    /// Plain linear tetrahedron (constant strain). Locks for ν → 0.5.
    #[default]
    T4,
    /// Average-nodal-pressure tetrahedron (Bonet & Burton 1998; Joldes, Wittek & Miller 2009):
    /// the element volume ratios `J` are averaged at the nodes by volume,
    /// `J_n = Σ V_e J_e / Σ V_e`, the element gets `J̄ = mean of its four J_n`, and the
    /// deformation gradient is rescaled to `F̄ = (J̄/J)^(1/3) F` before the stress is
    /// evaluated. Locking-free for nearly incompressible materials.
    T4Anp,
}

impl TetFormulation {
    /// Name as used in scene files and reports (`"T4"`, `"T4ANP"`).
    pub fn name(self) -> &'static str {
        match self {
            TetFormulation::T4 => "T4",
            TetFormulation::T4Anp => "T4ANP",
        }
    }
}

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

/// A material region: a constitutive law and a mass density.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solid {
    /// Hyperelastic law with its parameters.
    pub material: Material,
    /// Mass density (in the scene's units, e.g. kg/m³ or t/mm³). Only the physical critical
    /// time step uses it: Dynamic Relaxation uses fictitious masses.
    pub density: f64,
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

/// Precomputed data of one tetrahedron.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tet {
    pub nodes: [u32; 4],
    pub mat: u32,
    /// Reference volume.
    pub vol: f64,
    /// Reference shape-function gradients ∂N_a/∂X.
    pub g: [[f64; 3]; 4],
}

/// Precomputed data of one mean-strain hexahedron.
#[derive(Debug, Clone)]
pub(crate) struct Hex {
    pub nodes: [u32; 8],
    pub mat: u32,
    /// Reference volume.
    pub vol: f64,
    /// Mean (volume-averaged) shape-function gradients B̄_a = (1/V) ∫ ∂N_a/∂X dV.
    pub g: [[f64; 3]; 8],
    /// Hourglass stiffness matrix (8×8, acts on each displacement component).
    pub hg: [[f64; 8]; 8],
}

/// A Total Lagrangian model ready for the solvers.
#[derive(Debug, Clone)]
pub struct Model {
    pub(crate) reference: Vec<Point3<f64>>,
    pub(crate) node_ids: Vec<u64>,
    pub(crate) element_ids: Vec<u64>,
    pub(crate) solids: Vec<Solid>,
    pub(crate) options: ModelOptions,
    pub(crate) tets: Vec<Tet>,
    /// Mesh element index of each tet.
    pub(crate) tet_elem: Vec<u32>,
    pub(crate) hexes: Vec<Hex>,
    /// Mesh element index of each hex.
    pub(crate) hex_elem: Vec<u32>,
    /// Largest eigenvalue of each element's small-strain stiffness (mesh element order).
    pub(crate) stiffness_bound: Vec<f64>,
    /// Node → force slots (CSR): slot `s < 4·tets` is tet `s/4` local node `s%4`, then hexes.
    pub(crate) gather_ptr: Vec<u32>,
    pub(crate) gather_slot: Vec<u32>,
    /// ANP: 1 / Σ_{tets ∋ n} V_e per node (0 for nodes without tets).
    pub(crate) anp_inv_vol: Vec<f64>,
    /// `tets` in blocks of four (structure of arrays) for the SIMD kernels; derived from
    /// `tets` and `solids`, padded at the end.
    pub(crate) tet_blocks: Vec<TetBlock>,
    /// `hexes` in blocks of four for the SIMD kernel (derived, padded at the end).
    pub(crate) hex_blocks: Vec<HexBlock>,
    /// Number of tet slots (the first ones) of every node in `gather_slot` (derived).
    pub(crate) gather_tets: Vec<u32>,
}

/// Gauss points of the 2×2×2 rule (exact for the mean gradients of a trilinear hex).
const G: f64 = 0.577_350_269_189_625_8;

/// Natural coordinates of the hex nodes (Abaqus/VTK order), shared with bs-mesh.
pub(crate) use bs_mesh::HEX_REFERENCE as HEX_XI;

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

/// Mean gradients, volume and smallest Gauss-point Jacobian of a trilinear hex.
fn hex_mean_gradients(x: &[Point3<f64>; 8]) -> (f64, [[f64; 3]; 8], f64) {
    let mut vol = 0.0;
    let mut min_det = f64::INFINITY;
    let mut acc = [[0.0; 3]; 8];
    for gp in 0..8 {
        let p = [HEX_XI[gp][0] * G, HEX_XI[gp][1] * G, HEX_XI[gp][2] * G];
        // dN/dξ
        let mut dn = [[0.0; 3]; 8];
        for a in 0..8 {
            let s = HEX_XI[a];
            let f = [(1.0 + s[0] * p[0]), (1.0 + s[1] * p[1]), (1.0 + s[2] * p[2])];
            dn[a] = [
                0.125 * s[0] * f[1] * f[2],
                0.125 * s[1] * f[0] * f[2],
                0.125 * s[2] * f[0] * f[1],
            ];
        }
        // J_ij = ∂x_i/∂ξ_j
        let mut jm = nalgebra::Matrix3::zeros();
        for a in 0..8 {
            for i in 0..3 {
                for j in 0..3 {
                    jm[(i, j)] += x[a][i] * dn[a][j];
                }
            }
        }
        let det = jm.determinant();
        min_det = min_det.min(det);
        vol += det;
        let jinv = jm.try_inverse().unwrap_or_else(nalgebra::Matrix3::zeros);
        // ∂N/∂X = J⁻ᵀ ∂N/∂ξ, weighted by det (weights are 1).
        for a in 0..8 {
            for k in 0..3 {
                let mut s = 0.0;
                for j in 0..3 {
                    s += jinv[(j, k)] * dn[a][j];
                }
                acc[a][k] += s * det;
            }
        }
    }
    for row in acc.iter_mut() {
        for v in row.iter_mut() {
            *v /= vol;
        }
    }
    (vol, acc, min_det)
}

/// Flanagan–Belytschko stiffness hourglass matrix in the Total Lagrangian form of Joldes,
/// Wittek & Miller (2008): with the hourglass base vectors Γ_α (α = 1..4, entries ±1:
/// ξη, ηζ, ζξ, ξηζ at the nodes), the orthogonalised vectors
/// `γ_α = Γ_α − Σ_i (Γ_α · X_i) B̄_i` (X_i, B̄_i: nodal vectors of coordinate i and mean
/// gradient component i) annihilate every linear displacement field; the matrix is
/// `K_hg = k Σ_α γ_α γ_αᵀ` with `k = κ_hg · 2μ · V (B̄:B̄) / 3`.
///
/// Flanagan & Belytschko scale with the P-wave modulus `λ + 2μ`; for nearly incompressible
/// tissue (ν = 0.49–0.499) that makes the hourglass modes as stiff as the bulk and locks the
/// element (measured: 9× the T4ANP indentation force at ν = 0.499). Hourglass modes are
/// isochoric to first order, so the shear modulus is the physical scale: we use `2μ`, which
/// equals FB's `λ + 2μ` at ν = 0 and is softer above.
fn hourglass_matrix(
    x: &[Point3<f64>; 8],
    g: &[[f64; 3]; 8],
    vol: f64,
    el: &Elastic,
    kappa_hg: f64,
) -> [[f64; 8]; 8] {
    let mut gammas = [[0.0; 8]; 4];
    for (alpha, gamma) in gammas.iter_mut().enumerate() {
        let mut base = [0.0; 8];
        for a in 0..8 {
            let s = HEX_XI[a];
            base[a] = match alpha {
                0 => s[0] * s[1],
                1 => s[1] * s[2],
                2 => s[2] * s[0],
                _ => s[0] * s[1] * s[2],
            };
        }
        let mut proj = [0.0; 3];
        for (i, pi) in proj.iter_mut().enumerate() {
            *pi = (0..8).map(|a| base[a] * x[a][i]).sum();
        }
        for a in 0..8 {
            gamma[a] = base[a] - (0..3).map(|i| proj[i] * g[a][i]).sum::<f64>();
        }
    }
    let bb: f64 = g.iter().map(|r| r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sum();
    let k = kappa_hg * 2.0 * el.mu * vol * bb / 3.0;
    let mut hg = [[0.0; 8]; 8];
    for gamma in &gammas {
        for a in 0..8 {
            for b in 0..8 {
                hg[a][b] += k * gamma[a] * gamma[b];
            }
        }
    }
    hg
}

/// Largest eigenvalue of the small-strain element stiffness `V BᵀDB` (3n×3n): its nonzero
/// eigenvalues equal those of the 6×6 matrix `V D^(1/2) (B Bᵀ) D^(1/2)`.
fn consistent_stiffness_bound(g: &[[f64; 3]], vol: f64, el: &Elastic) -> f64 {
    let mut bbt = Tangent::zeros();
    for ga in g {
        let b = strain_rows(ga);
        bbt += b * b.transpose();
    }
    let d = el.small_strain_tangent();
    let eig = SymmetricEigen::new(d);
    let sqrt_d = eig.eigenvectors
        * Tangent::from_diagonal(&eig.eigenvalues.map(|v| v.max(0.0).sqrt()))
        * eig.eigenvectors.transpose();
    let m = sqrt_d * bbt * sqrt_d;
    let m = (m + m.transpose()) * 0.5;
    vol * SymmetricEigen::new(m).eigenvalues.max()
}

/// Small-strain B block (6×3) of a node with gradient `g`, Voigt (11,22,33,23,13,12) with
/// engineering shear.
fn strain_rows(g: &[f64; 3]) -> SMatrix<f64, 6, 3> {
    SMatrix::<f64, 6, 3>::from_row_slice(&[
        g[0], 0.0, 0.0, //
        0.0, g[1], 0.0, //
        0.0, 0.0, g[2], //
        0.0, g[2], g[1], //
        g[2], 0.0, g[0], //
        g[1], g[0], 0.0,
    ])
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
        let nn = mesh.nodes.len();
        let eid = |e: usize| mesh.element_ids.get(e).copied().unwrap_or(e as u64 + 1);
        let mut tets = Vec::new();
        let mut tet_elem = Vec::new();
        let mut hexes = Vec::new();
        let mut hex_elem = Vec::new();
        let mut stiffness_bound = vec![0.0; ne];
        for (e, elem) in mesh.elements.iter().enumerate() {
            let s = element_solid[e];
            if s >= solids.len() {
                return Err(ModelError::UnknownSolid {
                    element: e,
                    element_id: eid(e),
                    solid: s,
                    count: solids.len(),
                });
            }
            for &n in elem.nodes() {
                if n >= nn {
                    return Err(ModelError::NodeOutOfRange {
                        element: e,
                        element_id: eid(e),
                        node: n,
                        count: nn,
                    });
                }
            }
            let el = solids[s].material.elastic();
            match elem.kind() {
                ElementKind::Tet4 => {
                    let n = elem.nodes();
                    let x =
                        [mesh.nodes[n[0]], mesh.nodes[n[1]], mesh.nodes[n[2]], mesh.nodes[n[3]]];
                    let (vol, g) = tet_gradients(&x);
                    let scale =
                        (x[1] - x[0]).norm().max((x[2] - x[0]).norm()).max((x[3] - x[0]).norm());
                    if vol.is_nan() || vol <= 1e-12 * scale * scale * scale {
                        return Err(ModelError::InvertedElement {
                            element: e,
                            element_id: eid(e),
                            jacobian: vol,
                        });
                    }
                    stiffness_bound[e] = consistent_stiffness_bound(&g, vol, &el);
                    tets.push(Tet {
                        nodes: [n[0] as u32, n[1] as u32, n[2] as u32, n[3] as u32],
                        mat: s as u32,
                        vol,
                        g,
                    });
                    tet_elem.push(e as u32);
                }
                ElementKind::Hex8 => {
                    let n = elem.nodes();
                    let x: [Point3<f64>; 8] = std::array::from_fn(|a| mesh.nodes[n[a]]);
                    let (vol, g, min_det) = hex_mean_gradients(&x);
                    if !(min_det > 0.0 && vol > 0.0) {
                        return Err(ModelError::InvertedElement {
                            element: e,
                            element_id: eid(e),
                            jacobian: min_det,
                        });
                    }
                    let hg = hourglass_matrix(&x, &g, vol, &el, options.hourglass);
                    let hg_max =
                        SymmetricEigen::new(SMatrix::<f64, 8, 8>::from_fn(|i, j| hg[i][j]))
                            .eigenvalues
                            .max();
                    stiffness_bound[e] = consistent_stiffness_bound(&g, vol, &el) + hg_max.max(0.0);
                    hexes.push(Hex {
                        nodes: std::array::from_fn(|a| n[a] as u32),
                        mat: s as u32,
                        vol,
                        g,
                        hg,
                    });
                    hex_elem.push(e as u32);
                }
            }
        }
        // Node → slot map (CSR), slots in increasing order for a fixed summation order.
        let mut count = vec![0u32; nn + 1];
        for t in &tets {
            for &n in &t.nodes {
                count[n as usize + 1] += 1;
            }
        }
        for h in &hexes {
            for &n in &h.nodes {
                count[n as usize + 1] += 1;
            }
        }
        for i in 0..nn {
            count[i + 1] += count[i];
        }
        let gather_ptr = count.clone();
        let mut fill = count;
        let mut gather_slot = vec![0u32; gather_ptr[nn] as usize];
        let mut slot = 0u32;
        for t in &tets {
            for &n in &t.nodes {
                gather_slot[fill[n as usize] as usize] = slot;
                fill[n as usize] += 1;
                slot += 1;
            }
        }
        for h in &hexes {
            for &n in &h.nodes {
                gather_slot[fill[n as usize] as usize] = slot;
                fill[n as usize] += 1;
                slot += 1;
            }
        }
        let mut anp_vol = vec![0.0; nn];
        for t in &tets {
            for &n in &t.nodes {
                anp_vol[n as usize] += t.vol;
            }
        }
        let anp_inv_vol = anp_vol.iter().map(|&v| if v > 0.0 { 1.0 / v } else { 0.0 }).collect();
        let tet_blocks = tet_blocks(&tets, solids);
        let hex_blocks = hex_blocks(&hexes, solids);
        let gather_tets = tet_slot_counts(&gather_ptr, &gather_slot, tets.len());
        Ok(Model {
            reference: mesh.nodes.clone(),
            node_ids: if mesh.node_ids.len() == nn {
                mesh.node_ids.clone()
            } else {
                (1..=nn as u64).collect()
            },
            element_ids: (0..ne).map(eid).collect(),
            solids: solids.to_vec(),
            options,
            tets,
            tet_elem,
            hexes,
            hex_elem,
            stiffness_bound,
            gather_ptr,
            gather_slot,
            anp_inv_vol,
            tet_blocks,
            hex_blocks,
            gather_tets,
        })
    }

    /// Diagonal of the reference bounding box (0 without nodes).
    pub fn diagonal(&self) -> f64 {
        let pts = &self.reference;
        let Some(&first) = pts.first() else { return 0.0 };
        let (lo, hi) = pts.iter().fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        (hi - lo).norm()
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
        &self.element_ids
    }

    /// The options the model was built with.
    pub fn options(&self) -> ModelOptions {
        self.options
    }

    /// Number of (tetrahedra, hexahedra).
    pub fn counts(&self) -> (usize, usize) {
        (self.tets.len(), self.hexes.len())
    }

    pub(crate) fn slot_count(&self) -> usize {
        4 * self.tets.len() + 8 * self.hexes.len()
    }

    /// Physical critical time step of every element (mesh element order):
    /// `Δt_e = 2/ω_e`, `ω_e² = n λ_max(K_e) / (ρ V_e)` with `K_e` the small-strain stiffness
    /// (and hourglass stiffness for H8) and the element mass `ρ V_e` lumped equally on its
    /// `n` nodes. `λ_max(K_e)` scales with the P-wave modulus `λ + 2μ`, so this is
    /// `Δt_e = L_e / c` with `c = sqrt((λ+2μ)/ρ)` the dilatational wave speed and `L_e` a
    /// length computed from the shape-function derivatives (Flanagan & Belytschko's bound
    /// made exact for the element). It bounds the global stable step from below.
    pub fn critical_time_steps(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.element_count()];
        for (i, t) in self.tets.iter().enumerate() {
            let e = self.tet_elem[i] as usize;
            let m = self.solids[t.mat as usize].density * t.vol;
            out[e] = 2.0 * (m / (4.0 * self.stiffness_bound[e])).sqrt();
        }
        for (i, h) in self.hexes.iter().enumerate() {
            let e = self.hex_elem[i] as usize;
            let m = self.solids[h.mat as usize].density * h.vol;
            out[e] = 2.0 * (m / (8.0 * self.stiffness_bound[e])).sqrt();
        }
        out
    }

    /// Smallest physical critical time step and the element index that sets it.
    pub fn critical_time_step(&self) -> (f64, usize) {
        let steps = self.critical_time_steps();
        let mut best = (f64::INFINITY, 0);
        for (e, &s) in steps.iter().enumerate() {
            if s < best.0 {
                best = (s, e);
            }
        }
        best
    }

    /// Physical lumped nodal masses: each element's `ρ V` shared equally by its nodes.
    pub fn lumped_masses_into(&self, masses: &mut [f64]) {
        masses.iter_mut().for_each(|m| *m = 0.0);
        for t in &self.tets {
            let me = self.solids[t.mat as usize].density * t.vol / 4.0;
            for &n in &t.nodes {
                masses[n as usize] += me;
            }
        }
        for h in &self.hexes {
            let me = self.solids[h.mat as usize].density * h.vol / 8.0;
            for &n in &h.nodes {
                masses[n as usize] += me;
            }
        }
    }

    /// Fictitious lumped nodal masses for Dynamic Relaxation with unit time step `h = 1`:
    /// element `e` gets mass `m_e = n λ_max(K_e) / (4 f²)`, shared equally by its `n` nodes,
    /// so that its own critical step `2/ω_e` is `h/f`: the step is the fraction `f` of the
    /// element's critical step. `step_fraction = f < 1` keeps every element below its
    /// critical step; `f = 1.5` is 1.5× critical.
    pub fn dr_masses_into(&self, step_fraction: f64, masses: &mut [f64]) {
        masses.iter_mut().for_each(|m| *m = 0.0);
        let f2 = step_fraction * step_fraction;
        for (i, t) in self.tets.iter().enumerate() {
            let me = 4.0 * self.stiffness_bound[self.tet_elem[i] as usize] / (4.0 * f2);
            for &n in &t.nodes {
                masses[n as usize] += me / 4.0;
            }
        }
        for (i, h) in self.hexes.iter().enumerate() {
            let me = 8.0 * self.stiffness_bound[self.hex_elem[i] as usize] / (4.0 * f2);
            for &n in &h.nodes {
                masses[n as usize] += me / 8.0;
            }
        }
    }

    /// Total reference volume and volume-weighted sum of the small-strain shear moduli.
    pub(crate) fn volume_and_shear(&self) -> (f64, f64) {
        let mut v = 0.0;
        let mut mu = 0.0;
        for t in &self.tets {
            v += t.vol;
            mu += t.vol * self.solids[t.mat as usize].material.elastic().mu;
        }
        for h in &self.hexes {
            v += h.vol;
            mu += h.vol * self.solids[h.mat as usize].material.elastic().mu;
        }
        (v, mu)
    }

    /// Element index (mesh order) of tet `i`.
    pub(crate) fn tet_element(&self, i: usize) -> usize {
        self.tet_elem[i] as usize
    }

    /// Element index (mesh order) of hex `i`.
    pub(crate) fn hex_element(&self, i: usize) -> usize {
        self.hex_elem[i] as usize
    }
}
