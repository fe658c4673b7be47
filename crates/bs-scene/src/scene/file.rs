//! The scene file as a whole: `[mesh]`, `[output]` and `Scene` with its reading and checks.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::{
    Boundary, Contact, ElementChoice, Gravity, MaterialModel, Measurement, Region, Solver,
    UncertaintySection, Units,
};
use crate::SceneError;

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
    pub space: bs_image::Space,
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
    /// What `run --uncertainty` may use beyond the fit (held-out landmarks); none: the
    /// fit's posterior alone.
    pub uncertainty: Option<UncertaintySection>,
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
        if let Some(u) = &mut scene.uncertainty {
            for f in u.held_out.files_mut() {
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
            validate_region(i, r, scene.gravity.is_some())?;
        }
        for (i, b) in scene.boundaries.iter().enumerate() {
            validate_boundary(i, b)?;
        }
        for (i, m) in scene.measurements.iter().enumerate() {
            m.validate().map_err(|e| format!("[[measurement]] #{}: {e}", i + 1))?;
        }
        if let Some(g) = &scene.gravity {
            g.validate()?;
        }
        if let Some(u) = &scene.uncertainty {
            u.validate()?;
        }
        validate_solver(&scene.solver)
    }
}

/// A `[[region]]` (#`i`, 0-based): its moduli, density (required under gravity), cavity
/// pressure and the Ogden exponent's presence.
fn validate_region(i: usize, r: &Region, gravity: bool) -> Result<(), String> {
    let m = &r.material;
    m.moduli()
        .map_err(|e| format!("[[region]] #{} (elset '{}'), material: {e}", i + 1, r.elset))?;
    if let Some(d) = m.density
        && !(d > 0.0 && d.is_finite())
    {
        return Err(format!(
            "[[region]] #{} (elset '{}') material.density must be positive (kg/m³), got {d}",
            i + 1,
            r.elset
        ));
    }
    if gravity && m.density.is_none() {
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
            return Err(format!("[[region]] #{}: alpha is only used by model = \"ogden\"", i + 1));
        }
        _ => {}
    }
    Ok(())
}

/// A `[[boundary]]` (#`i`, 0-based): one load, one node selection, the keys that go with
/// each, finite positive sizes and values.
fn validate_boundary(i: usize, b: &Boundary) -> Result<(), String> {
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
        return Err(format!("[[boundary]] #{}: max_extrapolation goes with landmarks", i + 1));
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
            return Err(format!("[[boundary]] #{}: displacement values must be finite", i + 1));
        }
    }
    Ok(())
}

/// `[solver]`: a positive finite tolerance, at least one ramp step and one step.
fn validate_solver(solver: &Solver) -> Result<(), String> {
    if !(solver.tolerance > 0.0 && solver.tolerance.is_finite()) {
        return Err(format!(
            "[solver] tolerance must be positive (mesh length units), got {}",
            solver.tolerance
        ));
    }
    if solver.ramp_steps == 0 {
        return Err("[solver] ramp_steps must be at least 1 (default 200)".into());
    }
    if solver.max_steps == Some(0) {
        return Err("[solver] max_steps must be at least 1 (or left out for the default)".into());
    }
    Ok(())
}
