//! Scene files: what a user (or a validation script) writes to describe one brain-shift
//! computation. The keys are a contract: extend, never rename.
//!
//! ```toml
//! units = "mm"
//! space = "RAS"            # or "LPS"; the frame of the mesh (default RAS)
//! [mesh]
//! file = "brain.inp"
//! element = "t4anp"
//! [[region]]
//! elset = "BRAIN"
//! material = { model = "neo-hookean", youngs_modulus = 3000.0, poisson_ratio = 0.49, density = 1000.0 }
//! [[boundary]]
//! nset = "FIXED"
//! fix = ["x", "y", "z"]
//! [[boundary]]
//! nset = "CRANIOTOMY"
//! displacement = { x = 0.0, y = 0.0, z = -8.0 }
//! [contact]
//! skull = "skull.stl"
//! algorithm = "paper"
//! [solver]
//! kind = "dr"
//! tolerance = 1e-3
//! [output]
//! surfaces = ["VENTRICLES"]   # deformed boundary of these element sets (VTK, STL)
//! ```
//!
//! Paths are relative to the scene file. Unknown keys are errors (a misspelt key must not be
//! silently ignored).

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::SceneError;

/// Length unit of the mesh files. Stresses and moduli are always in Pa.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Units {
    /// Millimetres.
    Mm,
    /// Metres.
    M,
}

impl Units {
    /// Metres per mesh length unit.
    pub fn metres(self) -> f64 {
        match self {
            Units::Mm => 1e-3,
            Units::M => 1.0,
        }
    }

    /// The unit's symbol.
    pub fn symbol(self) -> &'static str {
        match self {
            Units::Mm => "mm",
            Units::M => "m",
        }
    }
}

/// The anatomical frame of the mesh coordinates (and of every displacement and output).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
pub enum SpaceName {
    /// Right–Anterior–Superior: NIfTI's world frame and 3D Slicer's (the default).
    #[default]
    #[serde(rename = "RAS")]
    Ras,
    /// Left–Posterior–Superior: DICOM's and ITK's frame.
    #[serde(rename = "LPS")]
    Lps,
}

impl SpaceName {
    /// The frame.
    pub fn space(self) -> bs_image::Space {
        match self {
            SpaceName::Ras => bs_image::Space::Ras,
            SpaceName::Lps => bs_image::Space::Lps,
        }
    }
}

/// Element technology.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ElementChoice {
    /// Linear tetrahedron.
    T4,
    /// Linear tetrahedron with average nodal pressure (locking-free).
    T4anp,
    /// Mean-strain hexahedron with hourglass control.
    H8,
}

impl ElementChoice {
    /// Every technology, in the order tables list them.
    pub const ALL: [ElementChoice; 3] =
        [ElementChoice::T4, ElementChoice::T4anp, ElementChoice::H8];

    /// The name used in scene files, reports and tables (`"t4"`, `"t4anp"`, `"h8"`).
    pub fn name(self) -> &'static str {
        match self {
            ElementChoice::T4 => "t4",
            ElementChoice::T4anp => "t4anp",
            ElementChoice::H8 => "h8",
        }
    }

    /// The technology of a name (the inverse of [`ElementChoice::name`]).
    pub fn from_name(name: &str) -> Option<ElementChoice> {
        ElementChoice::ALL.into_iter().find(|e| e.name() == name)
    }

    /// The mesh element kind this technology needs.
    pub fn mesh_kind(self) -> bs_mesh::ElementKind {
        match self {
            ElementChoice::H8 => bs_mesh::ElementKind::Hex8,
            ElementChoice::T4 | ElementChoice::T4anp => bs_mesh::ElementKind::Tet4,
        }
    }

    /// The solver's tetrahedral formulation (H8 meshes have no tetrahedra; T4ANP is the
    /// model's default there).
    pub fn tet_formulation(self) -> bs_dr::TetFormulation {
        match self {
            ElementChoice::T4 => bs_dr::TetFormulation::T4,
            ElementChoice::T4anp | ElementChoice::H8 => bs_dr::TetFormulation::T4Anp,
        }
    }
}

/// Constitutive model names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MaterialModel {
    /// Decoupled Neo-Hookean.
    NeoHookean,
    /// St Venant–Kirchhoff ("linear elastic" in a Total Lagrangian code).
    Svk,
    /// One-term Ogden.
    Ogden,
}

impl MaterialModel {
    /// The scene-file name (`"neo-hookean"`, `"svk"`, `"ogden"`).
    pub fn name(self) -> &'static str {
        match self {
            MaterialModel::NeoHookean => "neo-hookean",
            MaterialModel::Svk => "svk",
            MaterialModel::Ogden => "ogden",
        }
    }
}

/// Each name enum displays as the scene file spells it.
macro_rules! display_by_name {
    ($($t:ty),*) => {$(
        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
    )*};
}
display_by_name!(ElementChoice, MaterialModel, Algorithm, SolverKind);

/// A material: moduli from (E, ν) or (μ, κ), in Pa; density in kg/m³.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Constitutive model.
    pub model: MaterialModel,
    /// Young's modulus E [Pa].
    pub youngs_modulus: Option<f64>,
    /// Poisson's ratio ν.
    pub poisson_ratio: Option<f64>,
    /// Shear modulus μ [Pa] (alternative to E, ν).
    pub shear_modulus: Option<f64>,
    /// Bulk modulus κ [Pa] (alternative to E, ν).
    pub bulk_modulus: Option<f64>,
    /// Ogden exponent α (Ogden only).
    pub alpha: Option<f64>,
    /// Mass density [kg/m³]: the weight under `[gravity]` (required there); without gravity
    /// only Dynamic Relaxation's masses use it (default 1000).
    pub density: Option<f64>,
}

/// The density Dynamic Relaxation's masses use when a scene without gravity gives none
/// (kg/m³; the masses are fictitious, so any positive value serves).
pub const DEFAULT_DENSITY: f64 = 1000.0;

impl Material {
    /// The density given, or [`DEFAULT_DENSITY`].
    pub fn density_or_default(&self) -> f64 {
        self.density.unwrap_or(DEFAULT_DENSITY)
    }
}

/// Standard gravity (m/s²), the default of `[gravity] acceleration`.
pub const STANDARD_GRAVITY: f64 = 9.81;

/// The `[gravity]` table: the tissue's weight, and the cerebrospinal fluid that buoys it
/// where it has not drained.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gravity {
    /// Gravity's direction in the scene's frame (any length but zero): a supine patient's
    /// in RAS is `[0, -1, 0]` (posterior).
    pub direction: [f64; 3],
    /// Acceleration [m/s²]; default 9.81.
    #[serde(default = "standard_gravity")]
    pub acceleration: f64,
    /// The fluid below a level: there the tissue weighs `(ρ − ρ_fluid) g`, above it `ρ g`.
    pub fluid: Option<Fluid>,
}

fn standard_gravity() -> f64 {
    STANDARD_GRAVITY
}

/// A fluid filling the space below a level (cerebrospinal fluid drained above it).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fluid {
    /// Density [kg/m³] (cerebrospinal fluid: 1007).
    pub density: f64,
    /// A point of the fluid's surface (the plane through it normal to gravity), scene frame
    /// and units.
    pub level: [f64; 3],
}

impl Gravity {
    /// The unit direction (`None` for a zero or non-finite one).
    pub fn unit(&self) -> Option<[f64; 3]> {
        let [x, y, z] = self.direction;
        let n = (x * x + y * y + z * z).sqrt();
        (n > 0.0 && n.is_finite()).then(|| self.direction.map(|c| c / n))
    }

    /// Checks what the types cannot.
    pub fn validate(&self) -> Result<(), String> {
        if self.unit().is_none() {
            return Err(format!(
                "[gravity] direction {:?} has no direction: give a non-zero vector in the scene's \
                 frame (a supine patient in RAS: [0, -1, 0])",
                self.direction
            ));
        }
        if !(self.acceleration >= 0.0 && self.acceleration.is_finite()) {
            return Err(format!(
                "[gravity] acceleration must be finite and ≥ 0 (m/s², default 9.81), got {}",
                self.acceleration
            ));
        }
        if let Some(f) = &self.fluid {
            if !(f.density > 0.0 && f.density.is_finite()) {
                return Err(format!(
                    "[gravity] fluid.density must be positive (kg/m³; cerebrospinal fluid 1007), \
                     got {}",
                    f.density
                ));
            }
            if !f.level.iter().all(|c| c.is_finite()) {
                return Err("[gravity] fluid.level must be a finite point [x, y, z]".into());
            }
        }
        Ok(())
    }
}

/// Shear and bulk moduli resolved from a [`Material`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moduli {
    /// Shear modulus μ [Pa].
    pub mu: f64,
    /// Bulk modulus κ [Pa].
    pub kappa: f64,
}

impl Material {
    /// Resolves (μ, κ) from whichever pair was given, checking ranges.
    pub fn moduli(&self) -> Result<Moduli, String> {
        match (self.youngs_modulus, self.poisson_ratio, self.shear_modulus, self.bulk_modulus) {
            (Some(e), Some(nu), None, None) => {
                if !(e > 0.0 && e.is_finite()) {
                    return Err(format!("youngs_modulus must be positive, got {e}"));
                }
                if !(nu > -1.0 && nu < 0.5) {
                    return Err(format!(
                        "poisson_ratio must lie in (-1, 0.5), got {nu}; brain tissue is nearly \
                         incompressible, e.g. 0.49"
                    ));
                }
                Ok(Moduli { mu: e / (2.0 * (1.0 + nu)), kappa: e / (3.0 * (1.0 - 2.0 * nu)) })
            }
            (None, None, Some(mu), Some(kappa)) => {
                if !(mu > 0.0 && kappa > 0.0 && mu.is_finite() && kappa.is_finite()) {
                    return Err(format!(
                        "shear_modulus and bulk_modulus must be positive, got {mu} and {kappa}"
                    ));
                }
                Ok(Moduli { mu, kappa })
            }
            _ => Err("give either youngs_modulus and poisson_ratio, or shear_modulus and \
                      bulk_modulus (in Pa)"
                .into()),
        }
    }
}

/// A region: an element set and its material.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// Element set name in the mesh file; `"*"` means every element.
    pub elset: String,
    /// The material.
    pub material: Material,
    /// Resected: the region's elements leave the model (default false).
    #[serde(default)]
    pub resected: bool,
    /// With `resected`: the fluid pressure on the cavity's walls (Pa; default 0).
    pub cavity_pressure: Option<f64>,
}

/// A displacement component.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Component {
    /// x
    X,
    /// y
    Y,
    /// z
    Z,
}

impl Component {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        self as usize
    }
}

/// Final prescribed displacement values; unnamed components stay free.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Displacement {
    /// x component.
    pub x: Option<f64>,
    /// y component.
    pub y: Option<f64>,
    /// z component.
    pub z: Option<f64>,
}

impl Displacement {
    /// As an array of optional components.
    pub fn components(&self) -> [Option<f64>; 3] {
        [self.x, self.y, self.z]
    }
}

/// A sphere selecting the mesh's boundary nodes inside it (a craniotomy without a node set).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sphere {
    /// Centre, mesh frame and units.
    pub centre: [f64; 3],
    /// Radius, mesh units.
    pub radius: f64,
}

/// Default of `max_distance` (surface loads) and `max_extrapolation` (landmark loads), in mm.
pub const DEFAULT_MAX_DISTANCE_MM: f64 = 10.0;

/// A boundary condition on a node set (or from a file).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Boundary {
    /// Node set name in the mesh file.
    pub nset: Option<String>,
    /// Instead of `nset`: the mesh's boundary nodes inside this sphere.
    pub sphere: Option<Sphere>,
    /// Instead of `nset`: the mesh's boundary nodes whose nearest voxel of this NIfTI image
    /// is non-zero (the image's world frame, mm).
    pub mask: Option<PathBuf>,
    /// Components held at zero.
    pub fix: Option<Vec<Component>>,
    /// Final displacement on the 3-4-5 ramp.
    pub displacement: Option<Displacement>,
    /// CSV with `node_id,ux,uy,uz` per prescribed node (relative to the scene file).
    pub displacement_file: Option<PathBuf>,
    /// Intra-operative surface (.stl, .obj, .off; mesh frame and units): each selected node
    /// moves to its closest point on it.
    pub surface: Option<PathBuf>,
    /// Largest node-to-surface distance accepted (mesh units; default 10 mm).
    pub max_distance: Option<f64>,
    /// CSV of landmark pairs `x,y,z,x2,y2,z2` (pre-operative, intra-operative; mesh frame and
    /// units): the selected nodes move by the thin-plate spline of the landmark displacements.
    pub landmarks: Option<PathBuf>,
    /// Largest distance of a selected node outside the landmarks' bounding box (mesh units;
    /// default 10 mm).
    pub max_extrapolation: Option<f64>,
}

/// The landmark files of a `[[measurement]]`: one file of pairs (`.csv` with
/// `x,y,z,x2,y2,z2`, or an MNI `.tag` file with two volumes), or two files of points paired
/// by label (3D Slicer markups `.fcsv` / `.mrk.json`: pre-operative, intra-operative).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum LandmarkFiles {
    /// One file of pairs.
    Pairs(PathBuf),
    /// Pre-operative and intra-operative points, paired by label.
    Split([PathBuf; 2]),
}

impl LandmarkFiles {
    /// The files, comma-separated, for messages and reports.
    pub fn describe(&self) -> String {
        match self {
            LandmarkFiles::Pairs(f) => f.display().to_string(),
            LandmarkFiles::Split([a, b]) => format!("{}, {}", a.display(), b.display()),
        }
    }

    /// The files, for messages and path resolution.
    pub fn files_mut(&mut self) -> Vec<&mut PathBuf> {
        match self {
            LandmarkFiles::Pairs(f) => vec![f],
            LandmarkFiles::Split([a, b]) => vec![a, b],
        }
    }
}

/// Default of a measurement's `max_distance`, in mm: scanned points farther than this from
/// the brain's exposed surface are not matched.
pub const DEFAULT_MEASUREMENT_DISTANCE_MM: f64 = 20.0;

/// An intra-operative measurement fitted with the model as the regulariser (not imposed):
/// a scanned surface or landmark pairs.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measurement {
    /// The exposed brain surface as measured: a point cloud (.csv with columns x,y,z, .ply,
    /// .vtk/.vtp polydata, or the vertices of .stl/.obj/.off), in the scene's frame and units.
    pub points: Option<PathBuf>,
    /// Landmark pairs (pre-operative → intra-operative positions) anywhere in the brain.
    pub landmarks: Option<LandmarkFiles>,
    /// The boundary nodes the measurement may pull (points: the exposed surface; landmarks:
    /// where the unknown load acts, the craniotomy, whose displacement the fit finds).
    pub nset: Option<String>,
    /// The measurement's noise: the standard deviation of a point's error, mesh units.
    pub sigma: f64,
    /// Points the same scan took on the bone around the window (they do not move): the
    /// evidence for `rigid`.
    pub skull_points: Option<PathBuf>,
    /// Also estimate (and undo) a rigid misalignment of the scan, from `skull_points`.
    #[serde(default)]
    pub rigid: bool,
    /// Scanned points farther than this from the exposed surface are not matched (mesh
    /// units; default 20 mm).
    pub max_distance: Option<f64>,
    /// Whether the scanned patch's sliding along itself (which a scan cannot see) is
    /// resisted by a weak prior (default) or left to the model alone (docs/fit.md).
    #[serde(default)]
    pub sliding: Sliding,
    /// The direction the exposed surface sinks along, which the sliding prior leaves free
    /// (scene frame; default: the patch's mean inward normal, into the window).
    pub sag_direction: Option<[f64; 3]>,
}

/// What a scan cannot see, its patch sliding along itself: resisted by a weak prior across
/// the sag direction, or free (decided by the model alone).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sliding {
    /// Displacement across the sag direction resisted as the tissue resists a displacement
    /// of the window's size.
    #[default]
    Resisted,
    /// No prior: the elasticity, the skull and the held nodes alone decide.
    Free,
}

impl Measurement {
    /// Checks what the types cannot: one kind of data, its keys, positive numbers.
    pub fn validate(&self) -> Result<(), String> {
        match (&self.points, &self.landmarks) {
            (Some(_), Some(_)) | (None, None) => {
                return Err("give exactly one of points (a scanned surface) or landmarks".into());
            }
            (Some(_), None) if self.nset.is_none() => {
                return Err("points needs nset: the boundary nodes the scan may pull (e.g. \
                            nset = \"CRANIOTOMY\")"
                    .into());
            }
            (None, Some(_)) if self.nset.is_none() => {
                return Err("landmarks needs nset: the boundary nodes the shift comes through \
                            (e.g. nset = \"CRANIOTOMY\"); the fit finds their displacement"
                    .into());
            }
            (None, Some(_)) if self.skull_points.is_some() || self.rigid => {
                return Err("skull_points and rigid go with points (a scan), not landmarks".into());
            }
            (None, Some(_))
                if self.sliding != Sliding::Resisted || self.sag_direction.is_some() =>
            {
                return Err(
                    "sliding and sag_direction go with points (a scan), not landmarks".into()
                );
            }
            _ => {}
        }
        if !(self.sigma > 0.0 && self.sigma.is_finite()) {
            return Err(format!(
                "sigma must be positive (the measurement's noise, mesh units), got {}",
                self.sigma
            ));
        }
        if let Some(d) = self.max_distance
            && !(d > 0.0 && d.is_finite())
        {
            return Err(format!("max_distance must be positive (mesh units), got {d}"));
        }
        if let Some(d) = self.sag_direction {
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if !(n > 0.0 && n.is_finite()) {
                return Err(format!(
                    "sag_direction must be a non-zero vector [x, y, z] (scene frame), got {d:?}"
                ));
            }
            if self.sliding == Sliding::Free {
                return Err("sag_direction is the direction the sliding prior leaves free: \
                            with sliding = \"free\" there is no prior; drop one of them"
                    .into());
            }
        }
        if self.rigid && self.skull_points.is_none() {
            return Err("rigid = true needs skull_points: the misalignment is estimated from \
                        bone, which does not move; fitted to the brain alone it would explain \
                        the shift as misalignment (docs/fit.md)"
                .into());
        }
        if self.skull_points.is_some() && !self.rigid {
            return Err("skull_points are only used to estimate the misalignment: add rigid = \
                        true, or drop skull_points"
                .into());
        }
        Ok(())
    }
}

/// Contact handler names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Algorithm {
    /// The paper's algorithm.
    Paper,
    /// The paper's algorithm with temporal coherence.
    Coherent,
    /// parry3d's closest-point query.
    Parry,
    /// Every face, every time (reference).
    BruteForce,
}

/// The rigid skull.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Contact {
    /// Closed, outward-oriented triangle surface (.stl, .obj, .off).
    pub skull: PathBuf,
    /// Handler; default `paper`.
    #[serde(default = "default_algorithm")]
    pub algorithm: Algorithm,
}

impl Algorithm {
    /// The scene-file name.
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Paper => "paper",
            Algorithm::Coherent => "coherent",
            Algorithm::Parry => "parry",
            Algorithm::BruteForce => "brute-force",
        }
    }
}

fn default_algorithm() -> Algorithm {
    Algorithm::Paper
}

/// Solver kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// Semismooth Newton–Krylov with the two-level preconditioner (the default): any
    /// element, kinematic contact linearised on its active set.
    #[serde(rename = "newton-krylov")]
    NewtonKrylov,
    /// Dynamic Relaxation (the paper's solver; the baseline).
    Dr,
    /// Static Newton–Raphson with a direct factorisation (reference; T4/H8, no contact).
    Newton,
}

impl SolverKind {
    /// The name used in scene files and reports.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::NewtonKrylov => "newton-krylov",
            SolverKind::Dr => "dr",
            SolverKind::Newton => "newton",
        }
    }
}

/// Solver settings.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Solver {
    /// Default `newton-krylov`.
    #[serde(default = "default_solver")]
    pub kind: SolverKind,
    /// Error-estimate tolerance in mesh length units; default 1e-3.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// DR steps of the 3-4-5 load ramp; default 200 (DR only). Large displacements on coarse meshes
    /// need a longer ramp (the prescribed nodes otherwise outrun their neighbours and
    /// invert elements).
    #[serde(default = "default_ramp_steps")]
    pub ramp_steps: usize,
    /// The iteration budget: Newton iterations over all load levels (newton-krylov, default
    /// 300) or DR steps (dr, default 200 000); not used by `newton`. Extreme loads (the
    /// 40 mm ellipsoid on a fine mesh) may need more.
    #[serde(default)]
    pub max_steps: Option<usize>,
}

fn default_ramp_steps() -> usize {
    bs_dr::DrParams::default().ramp_steps
}

fn default_solver() -> SolverKind {
    SolverKind::NewtonKrylov
}

fn default_tolerance() -> f64 {
    1e-3
}

impl Default for Solver {
    fn default() -> Self {
        Solver {
            kind: default_solver(),
            tolerance: default_tolerance(),
            ramp_steps: default_ramp_steps(),
            max_steps: None,
        }
    }
}

/// The `[mesh]` table.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSection {
    /// Volume mesh file (.inp, .msh, .vtu, .vtk), relative to the scene file.
    pub file: PathBuf,
    /// Element technology; default t4anp for tets, h8 for hexes.
    pub element: Option<ElementChoice>,
}

/// The `[output]` table: result files beyond those every run writes.
#[derive(Debug, Clone, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// Element sets whose deformed boundary surface `run` writes as
    /// `surface-NAME.vtk` and `surface-NAME.stl` (the scene's frame and unit), e.g. the
    /// ventricles for a Hausdorff distance against an intra-operative segmentation.
    #[serde(default)]
    pub surfaces: Vec<String>,
}

/// A parsed scene, paths resolved against the scene file's folder.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Length unit of the mesh files.
    pub units: Units,
    /// Anatomical frame of the mesh files: `"RAS"` (default) or `"LPS"`.
    #[serde(default)]
    pub space: SpaceName,
    /// The brain mesh.
    pub mesh: MeshSection,
    /// Material regions.
    #[serde(rename = "region", default)]
    pub regions: Vec<Region>,
    /// Boundary conditions.
    #[serde(rename = "boundary", default)]
    pub boundaries: Vec<Boundary>,
    /// Intra-operative measurements fitted with the model.
    #[serde(rename = "measurement", default)]
    pub measurements: Vec<Measurement>,
    /// The skull; none means no contact.
    pub contact: Option<Contact>,
    /// Solver settings.
    #[serde(default)]
    pub solver: Solver,
    /// Extra outputs.
    #[serde(default)]
    pub output: OutputSection,
    /// Gravity (and the fluid that buoys the brain below its level); none: no body force.
    pub gravity: Option<Gravity>,
}

impl Scene {
    /// Reads and checks a scene file; relative paths become relative to its folder.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let err = |message: String| SceneError::Scene { file: path.to_path_buf(), message };
        let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read: {e}")))?;
        let mut scene = Scene::parse(&text).map_err(err)?;
        let dir = path.parent().unwrap_or(Path::new(""));
        scene.mesh.file = dir.join(&scene.mesh.file);
        if let Some(c) = &mut scene.contact {
            c.skull = dir.join(&c.skull);
        }
        for b in &mut scene.boundaries {
            for f in [&mut b.displacement_file, &mut b.mask, &mut b.surface, &mut b.landmarks]
                .into_iter()
                .flatten()
            {
                *f = dir.join(&*f);
            }
        }
        for m in &mut scene.measurements {
            let mut files: Vec<&mut PathBuf> =
                [&mut m.points, &mut m.skull_points].into_iter().flatten().collect();
            if let Some(l) = &mut m.landmarks {
                files.extend(l.files_mut());
            }
            for f in files {
                *f = dir.join(&*f);
            }
        }
        Ok(scene)
    }

    /// Parses scene text and checks what the types cannot (ranges, exclusive keys).
    pub fn parse(text: &str) -> Result<Scene, String> {
        let scene: Scene = toml::from_str(text).map_err(|e| {
            // toml's message names the line, column and key; keep it whole.
            e.to_string().trim_end().to_string()
        })?;
        scene.validate()?;
        Ok(scene)
    }

    /// Checks what the types cannot (ranges, exclusive keys): [`Scene::parse`] does it for
    /// scene text; front ends that build a scene otherwise (the Python bindings' scene from
    /// arrays) call it themselves.
    pub fn validate(&self) -> Result<(), String> {
        let scene = self;
        if scene.regions.is_empty() {
            return Err(
                "no [[region]]: give at least one, e.g. elset = \"*\" with a material".into()
            );
        }
        for (i, r) in scene.regions.iter().enumerate() {
            let m = &r.material;
            m.moduli().map_err(|e| {
                format!("[[region]] #{} (elset '{}'), material: {e}", i + 1, r.elset)
            })?;
            if let Some(d) = m.density
                && !(d > 0.0 && d.is_finite())
            {
                return Err(format!(
                    "[[region]] #{} (elset '{}') material.density must be positive (kg/m³), got {d}",
                    i + 1,
                    r.elset
                ));
            }
            if scene.gravity.is_some() && m.density.is_none() {
                return Err(format!(
                    "[[region]] #{} (elset '{}'): [gravity] weighs each region by its density: \
                     give material.density (kg/m³; brain tissue about 1040)",
                    i + 1,
                    r.elset
                ));
            }
            if let Some(p) = r.cavity_pressure {
                if !r.resected {
                    return Err(format!(
                        "[[region]] #{} (elset '{}'): cavity_pressure goes with resected = true",
                        i + 1,
                        r.elset
                    ));
                }
                if !(p >= 0.0 && p.is_finite()) {
                    return Err(format!(
                        "[[region]] #{} (elset '{}'): cavity_pressure must be finite and ≥ 0 (Pa), \
                         got {p}",
                        i + 1,
                        r.elset
                    ));
                }
            }
            match (m.model, m.alpha) {
                (MaterialModel::Ogden, None) => {
                    return Err(format!(
                        "[[region]] #{}: model = \"ogden\" needs alpha (brain: alpha = -4.7)",
                        i + 1
                    ));
                }
                (MaterialModel::NeoHookean | MaterialModel::Svk, Some(_)) => {
                    return Err(format!(
                        "[[region]] #{}: alpha is only used by model = \"ogden\"",
                        i + 1
                    ));
                }
                _ => {}
            }
        }
        for (i, b) in scene.boundaries.iter().enumerate() {
            let given = [
                b.fix.is_some(),
                b.displacement.is_some(),
                b.displacement_file.is_some(),
                b.surface.is_some(),
                b.landmarks.is_some(),
            ];
            if given.iter().filter(|&&g| g).count() != 1 {
                return Err(format!(
                    "[[boundary]] #{}: give exactly one of fix, displacement or displacement_file \
                     (or an intra-operative load: surface or landmarks)",
                    i + 1
                ));
            }
            let selections = [b.nset.is_some(), b.sphere.is_some(), b.mask.is_some()];
            let selected = selections.iter().filter(|&&g| g).count();
            if b.displacement_file.is_some() && (b.sphere.is_some() || b.mask.is_some()) {
                return Err(format!(
                    "[[boundary]] #{}: displacement_file names its nodes; drop sphere or mask",
                    i + 1
                ));
            }
            if b.displacement_file.is_none() && selected == 0 {
                return Err(format!(
                    "[[boundary]] #{}: nset is required with fix or displacement (or select \
                     the nodes with sphere or mask)",
                    i + 1
                ));
            }
            if selected > 1 {
                return Err(format!(
                    "[[boundary]] #{}: select the nodes with exactly one of nset, sphere or mask",
                    i + 1
                ));
            }
            if b.max_distance.is_some() && b.surface.is_none() {
                return Err(format!("[[boundary]] #{}: max_distance goes with surface", i + 1));
            }
            if b.max_extrapolation.is_some() && b.landmarks.is_none() {
                return Err(format!(
                    "[[boundary]] #{}: max_extrapolation goes with landmarks",
                    i + 1
                ));
            }
            for (key, v) in [
                ("max_distance", b.max_distance),
                ("max_extrapolation", b.max_extrapolation),
                ("sphere.radius", b.sphere.map(|s| s.radius)),
            ] {
                if let Some(v) = v
                    && !(v > 0.0 && v.is_finite())
                {
                    return Err(format!(
                        "[[boundary]] #{}: {key} must be positive (mesh units), got {v}",
                        i + 1
                    ));
                }
            }
            if let Some(s) = &b.sphere
                && !s.centre.iter().all(|c| c.is_finite())
            {
                return Err(format!("[[boundary]] #{}: sphere.centre must be finite", i + 1));
            }
            if let Some(d) = &b.displacement {
                if d.components().iter().all(Option::is_none) {
                    return Err(format!(
                        "[[boundary]] #{}: displacement names no component (x, y or z)",
                        i + 1
                    ));
                }
                if d.components().iter().flatten().any(|v| !v.is_finite()) {
                    return Err(format!(
                        "[[boundary]] #{}: displacement values must be finite",
                        i + 1
                    ));
                }
            }
        }
        for (i, m) in scene.measurements.iter().enumerate() {
            m.validate().map_err(|e| format!("[[measurement]] #{}: {e}", i + 1))?;
        }
        if let Some(g) = &scene.gravity {
            g.validate()?;
        }
        if !(scene.solver.tolerance > 0.0 && scene.solver.tolerance.is_finite()) {
            return Err(format!(
                "[solver] tolerance must be positive (mesh length units), got {}",
                scene.solver.tolerance
            ));
        }
        if scene.solver.ramp_steps == 0 {
            return Err("[solver] ramp_steps must be at least 1 (default 200)".into());
        }
        if scene.solver.max_steps == Some(0) {
            return Err(
                "[solver] max_steps must be at least 1 (or left out for the default)".into()
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
units = "mm"
[mesh]
file = "brain.inp"
element = "t4anp"
[[region]]
elset = "BRAIN"
material = { model = "neo-hookean", youngs_modulus = 3000.0, poisson_ratio = 0.49, density = 1000.0 }
[[boundary]]
nset = "FIXED"
fix = ["x", "y", "z"]
[[boundary]]
nset = "CRANIOTOMY"
displacement = { x = 0.0, y = 0.0, z = -8.0 }
[contact]
skull = "skull.stl"
algorithm = "paper"
[solver]
kind = "dr"
tolerance = 1e-3
"#;

    #[test]
    fn the_documented_example_parses() {
        let s = Scene::parse(GOOD).unwrap();
        assert_eq!(s.units, Units::Mm);
        assert_eq!(s.mesh.element, Some(ElementChoice::T4anp));
        let m = s.regions[0].material.moduli().unwrap();
        // E = 3000, nu = 0.49: mu = E / 2(1+nu), kappa = E / 3(1-2nu).
        approx::assert_relative_eq!(m.mu, 3000.0 / 2.98, epsilon = 1e-12);
        approx::assert_relative_eq!(m.kappa, 3000.0 / 0.06, epsilon = 1e-9);
        assert_eq!(
            s.boundaries[1].displacement.unwrap().components(),
            [Some(0.0), Some(0.0), Some(-8.0)]
        );
        assert_eq!(s.contact.unwrap().algorithm, Algorithm::Paper);
        assert_eq!(
            s.solver,
            Solver { kind: SolverKind::Dr, tolerance: 1e-3, ramp_steps: 200, max_steps: None }
        );
    }

    #[test]
    fn a_misspelt_key_is_an_error_naming_it_and_its_line() {
        let bad = GOOD.replace("tolerance = 1e-3", "tolerence = 1e-3");
        let e = Scene::parse(&bad).unwrap_err();
        assert!(e.contains("tolerence"), "{e}");
        assert!(e.contains("line 20"), "{e}");
    }

    #[test]
    fn range_and_exclusivity_mistakes_are_errors() {
        let cases = [
            ("poisson_ratio = 0.49", "poisson_ratio = 0.5", "poisson_ratio must lie in (-1, 0.5)"),
            ("youngs_modulus = 3000.0", "youngs_modulus = -3.0", "youngs_modulus must be positive"),
            ("fix = [\"x\", \"y\", \"z\"]", "fix = [\"x\", \"w\"]", "unknown variant `w`"),
            ("units = \"mm\"", "units = \"cm\"", "unknown variant `cm`"),
            ("kind = \"dr\"", "kind = \"explicit\"", "unknown variant `explicit`"),
            ("tolerance = 1e-3", "tolerance = 0.0", "tolerance must be positive"),
            ("z = -8.0 }", "z = -8.0 }\nfix = [\"x\"]", "exactly one of fix, displacement"),
            ("model = \"neo-hookean\"", "model = \"ogden\"", "needs alpha"),
        ];
        for (from, to, expect) in cases {
            let e = Scene::parse(&GOOD.replace(from, to)).unwrap_err();
            assert!(e.contains(expect), "{to}: {e}");
        }
    }

    #[test]
    fn defaults_apply_when_optional_tables_are_missing() {
        let s = Scene::parse(
            "units = \"m\"\n[mesh]\nfile = \"a.msh\"\n[[region]]\nelset = \"*\"\n\
             material = { model = \"svk\", shear_modulus = 1000.0, bulk_modulus = 50000.0 }\n",
        )
        .unwrap();
        assert_eq!(s.solver, Solver::default());
        assert_eq!(s.contact, None);
        assert_eq!(s.regions[0].material.density, None);
        assert_eq!(s.regions[0].material.density_or_default(), DEFAULT_DENSITY);
        assert_eq!(s.units, Units::M);
    }
}
