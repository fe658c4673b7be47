//! What an element is made of: a [`Solid`] (constitutive law and density) and, for
//! tetrahedra, the [`TetFormulation`].

use bs_material::Material;

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

/// A material region: a constitutive law and a mass density.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solid {
    /// Hyperelastic law with its parameters.
    pub material: Material,
    /// Mass density (in the scene's units, e.g. kg/m³ or t/mm³). Only the physical critical
    /// time step uses it: Dynamic Relaxation uses fictitious masses.
    pub density: f64,
}
