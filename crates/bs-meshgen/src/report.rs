//! What meshing produced, measured: the report `brainshift mesh` prints.

use std::fmt;

use crate::ElementType;
use crate::quality::QualityStats;

/// Volume of one element set against the labelmap.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionVolume {
    /// Element set name.
    pub name: String,
    /// Number of elements.
    pub elements: usize,
    /// Mesh volume, mm³.
    pub mesh_volume: f64,
    /// Voxel count × voxel volume of its labels, mm³.
    pub label_volume: f64,
}

/// The measured result of meshing a labelmap.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshReport {
    /// Element type built.
    pub element: ElementType,
    /// Target edge length (lattice or grid spacing), mm.
    pub size: f64,
    /// Number of nodes.
    pub nodes: usize,
    /// Number of elements.
    pub elements: usize,
    /// Element quality.
    pub quality: QualityStats,
    /// The proven dihedral-angle bounds of the method, degrees (T4 stuffing; `None` for H8).
    pub dihedral_bound_deg: Option<(f64, f64)>,
    /// Whole-brain mesh volume, mm³.
    pub mesh_volume: f64,
    /// Brain voxel count × voxel volume, mm³.
    pub label_volume: f64,
    /// Per element set (BRAIN and each region).
    pub regions: Vec<RegionVolume>,
    /// Lattice vertices warped onto the brain surface (T4).
    pub warped: usize,
    /// Nodes in FIXED.
    pub fixed_nodes: usize,
    /// Nodes in CRANIOTOMY.
    pub craniotomy_nodes: usize,
    /// Skull surface vertices and triangles.
    pub skull_vertices: usize,
    /// Skull triangles.
    pub skull_triangles: usize,
    /// Smallest estimated brain-to-skull gap over the brain's surface nodes, mm (from the
    /// cavity's distance field; the exact gap is checked by the scene).
    pub min_gap_estimate: f64,
    /// Wall time of each step, seconds.
    pub timings: Vec<(&'static str, f64)>,
}

impl MeshReport {
    /// Relative difference of the mesh volume from the voxel volume.
    pub fn volume_error(&self) -> f64 {
        self.mesh_volume / self.label_volume - 1.0
    }

    /// Total wall time, seconds.
    pub fn seconds(&self) -> f64 {
        self.timings.iter().map(|t| t.1).sum()
    }
}

impl fmt::Display for MeshReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} mesh at {} mm: {} nodes, {} elements",
            self.element.name(),
            self.size,
            self.nodes,
            self.elements
        )?;
        match self.element {
            ElementType::T4 => {
                write!(
                    f,
                    "  dihedral angles {:.2}°..{:.2}°",
                    self.quality.min_dihedral_deg, self.quality.max_dihedral_deg
                )?;
                if let Some((lo, hi)) = self.dihedral_bound_deg {
                    write!(f, " (stuffing bound {lo}°..{hi}°)")?;
                }
                writeln!(f, ", min radius ratio {:.3}", self.quality.min_radius_ratio)?;
            }
            ElementType::H8 => {
                writeln!(f, "  min scaled Jacobian {:.3}", self.quality.min_scaled_jacobian)?
            }
        }
        writeln!(f, "  inverted elements: {}", self.quality.inverted)?;
        writeln!(
            f,
            "  volume {:.0} mm³ vs {:.0} mm³ of labelled voxels ({:+.2}%)",
            self.mesh_volume,
            self.label_volume,
            100.0 * self.volume_error()
        )?;
        for r in &self.regions {
            writeln!(
                f,
                "  set {:<12} {:>8} elements, {:>10.0} mm³ vs {:>10.0} mm³ voxels ({:+.2}%)",
                r.name,
                r.elements,
                r.mesh_volume,
                r.label_volume,
                100.0 * (r.mesh_volume / r.label_volume - 1.0)
            )?;
        }
        writeln!(
            f,
            "  FIXED {} nodes, CRANIOTOMY {} nodes; skull {} vertices, {} triangles, min gap ≈ {:.2} mm",
            self.fixed_nodes,
            self.craniotomy_nodes,
            self.skull_vertices,
            self.skull_triangles,
            self.min_gap_estimate
        )?;
        let steps: Vec<String> =
            self.timings.iter().map(|(n, t)| format!("{n} {:.3}", t)).collect();
        write!(f, "  time {:.3} s ({})", self.seconds(), steps.join(", "))
    }
}
