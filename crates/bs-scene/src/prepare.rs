//! Preparation: a scene file becomes a [`Prepared`] scene — its files read, its names
//! resolved, everything a run needs checked before anything is computed. `brainshift check`
//! and `brainshift run` both start here, so a scene that passes `check` fails in `run` only
//! for numerical reasons.

use std::path::{Path, PathBuf};

use bs_mesh::{Mesh, TriSurface};

use crate::SceneError;
use crate::boundary::{names, resolve_boundaries_with_notes};
use crate::scene::{ElementChoice, Scene, SolverKind, Units};

/// A scene with its files read and its names resolved.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The scene file.
    pub path: PathBuf,
    /// The parsed scene.
    pub scene: Scene,
    /// The brain mesh.
    pub mesh: Mesh,
    /// Element technology after defaults.
    pub element: ElementChoice,
    /// Region index of every element.
    pub region_of_element: Vec<usize>,
    /// Per node and component: the final displacement it is held at, or free (see
    /// [`crate::boundary::Prescribed`]).
    pub prescribed: Vec<[Option<f64>; 3]>,
    /// The skull, if the scene has contact.
    pub skull: Option<TriSurface>,
    /// Things worth knowing that do not stop a run.
    pub warnings: Vec<String>,
    /// One line per intra-operative load (surface, landmarks) or sphere/mask selection.
    pub loads: Vec<String>,
    /// The `[[measurement]]` tables with their files read (fitted, not imposed).
    pub measurements: Vec<crate::measure::Measured>,
    /// What the resected regions removed (their elements are not in `mesh`).
    pub resection: Option<crate::resection::Resection>,
}

impl Prepared {
    /// Reads the scene, the mesh and the skull and resolves sets; every error names the
    /// file and the key or entity.
    pub fn load(scene_path: &Path) -> Result<Prepared, SceneError> {
        let scene = Scene::load(scene_path)?;
        Prepared::from_scene(scene_path, scene)
    }

    /// [`Prepared::load`] for a scene already parsed (`scene_path` names it in messages;
    /// its paths must already be resolved).
    pub fn from_scene(scene_path: &Path, scene: Scene) -> Result<Prepared, SceneError> {
        let sp = scene_path.to_path_buf();
        let mesh = bs_mesh::io::read_mesh(&scene.mesh.file).map_err(|e| SceneError::Read {
            scene: sp.clone(),
            key: "[mesh] file".into(),
            message: e.to_string(),
        })?;
        let skull = match &scene.contact {
            None => None,
            Some(c) => Some(bs_mesh::io::read_surface(&c.skull).map_err(|e| SceneError::Read {
                scene: sp.clone(),
                key: "[contact] skull".into(),
                message: e.to_string(),
            })?),
        };
        Prepared::from_parts(scene_path, scene, mesh, skull)
    }

    /// [`Prepared::from_scene`] with the mesh and the skull already in memory (the Python
    /// bindings' scene from arrays): `skull` must be given exactly when the scene has a
    /// `[contact]` table, whose `skull` path then only names it in messages. Everything
    /// else is checked as for a scene file.
    pub fn from_parts(
        scene_path: &Path,
        scene: Scene,
        mesh: Mesh,
        skull: Option<TriSurface>,
    ) -> Result<Prepared, SceneError> {
        let sp = scene_path.to_path_buf();
        let report = mesh.validate();
        if let Some(first) = report.first_error() {
            return Err(SceneError::Mesh {
                file: scene.mesh.file.clone(),
                count: report.errors.len(),
                first: first.to_string(),
            });
        }
        let mut warnings = Vec::new();
        if !report.unused_node_ids.is_empty() {
            warnings.push(format!(
                "{} nodes belong to no element and are held where they are (e.g. node {})",
                report.unused_node_ids.len(),
                report.unused_node_ids[0]
            ));
        }
        let element = element_of(&sp, &scene, &mesh)?;
        let mut region_of_element = regions(&sp, &scene, &mesh)?;
        output_surfaces(&sp, &scene, &mesh)?;
        let mut mesh = mesh;
        let resection = crate::resection::apply(&sp, &scene, &mut mesh, &mut region_of_element)?;
        let (prescribed, load_notes) = resolve_boundaries_with_notes(&sp, &scene, &mesh)?;
        let skull = match (&scene.contact, skull) {
            (None, None) => None,
            (Some(c), Some(s)) => {
                s.require_closed_outward().map_err(|e| SceneError::Skull {
                    scene: sp.clone(),
                    skull: c.skull.clone(),
                    message: e.to_string(),
                })?;
                Some(s)
            }
            (Some(_), None) => {
                return Err(SceneError::Unsupported {
                    scene: sp,
                    message: "the scene has a [contact] table but no skull surface was given"
                        .into(),
                });
            }
            (None, Some(_)) => {
                return Err(SceneError::Unsupported {
                    scene: sp,
                    message: "a skull surface was given but the scene has no [contact] table; \
                              add one to use it"
                        .into(),
                });
            }
        };
        let measurements = crate::measure::read::read_measurements(
            &sp,
            &scene,
            &mesh,
            &prescribed,
            skull.as_ref(),
        )?;
        if let Some(e) = scene.gravity.as_ref().and_then(|g| g.estimate.as_ref()) {
            crate::measure::read::check_estimate_data(e, &measurements)
                .map_err(|message| SceneError::Scene { file: sp.clone(), message })?;
        }
        let prescribed = crate::measure::read::control(&mesh, prescribed, &measurements);
        let mut load_notes = load_notes;
        load_notes.extend(measurements.iter().map(crate::measure::Measured::note));
        let n_constrained = prescribed.iter().filter(|p| p.iter().any(Option::is_some)).count();
        let weighs = scene.gravity.as_ref().is_some_and(|g| g.acceleration > 0.0)
            || scene.regions.iter().any(|r| r.resected && r.cavity_pressure.unwrap_or(0.0) > 0.0);
        if n_constrained == 0 && skull.is_none() && measurements.is_empty() {
            return Err(SceneError::Unsupported {
                scene: sp,
                message: "nothing to compute: no node has a prescribed or fixed displacement \
                          and there is no skull; add a [[boundary]] that moves nodes (or, with \
                          [gravity], one that holds the brain)"
                    .into(),
            });
        }
        if measurements.is_empty()
            && !weighs
            && !prescribed.iter().flatten().flatten().any(|v| *v != 0.0)
        {
            return Err(SceneError::Unsupported {
                scene: sp,
                message: "nothing to compute: no boundary condition moves a node (every \
                          prescribed displacement is zero) and there is no [gravity], so the \
                          brain does not deform; add a [[boundary]] with a non-zero \
                          displacement or a [gravity] table"
                    .into(),
            });
        }
        unit_sanity(&sp, &scene, &mesh, &prescribed, &mut warnings)?;
        for r in &scene.regions {
            if let Some(e) = r.material.youngs_modulus.filter(|e| !(10.0..=1e7).contains(e)) {
                warnings.push(format!(
                    "region '{}': youngs_modulus = {e} Pa is far from soft tissue (brain: ~3000 Pa); \
                     moduli are in Pa",
                    r.elset
                ));
            }
        }
        if scene.contact.is_some()
            && !prescribed.iter().any(|p| p.iter().all(|c| c.is_some_and(|v| v == 0.0)))
        {
            warnings.push(
                "no node is fully fixed: a brain held only by the craniotomy inside a frictionless \
                 skull can twist about the push axis; fix the brain-stem nodes"
                    .into(),
            );
        }
        let mut prescribed = prescribed;
        crate::resection::hold_unused(&mesh, &mut prescribed);
        if resection.is_some() {
            crate::resection::require_support(&sp, &scene, &mesh, &prescribed)?;
        }
        let prepared = Prepared {
            path: sp,
            scene,
            mesh,
            element,
            region_of_element,
            prescribed,
            skull,
            warnings,
            loads: load_notes,
            measurements,
            resection,
        };
        prepared.require_supported()?;
        crate::imposed::check(prepared.imposed())?;
        Ok(prepared)
    }

    /// The view of this scene the imposed-data checks read.
    pub(crate) fn imposed(&self) -> crate::imposed::Imposed<'_> {
        crate::imposed::Imposed {
            path: &self.path,
            scene: &self.scene,
            mesh: &self.mesh,
            prescribed: &self.prescribed,
        }
    }

    /// Refuses combinations the chosen solver cannot run, so `check` rejects everything
    /// `run` would reject before solving.
    pub fn require_supported(&self) -> Result<(), SceneError> {
        let unsupported =
            |message: String| Err(SceneError::Unsupported { scene: self.path.clone(), message });
        if self.scene.solver.kind == SolverKind::Newton && self.element == ElementChoice::T4anp {
            return unsupported(
                "[solver] kind = \"newton\" does not support element = \"t4anp\" (its \
                     tangent is not assembled); use kind = \"newton-krylov\" (the default) or \
                     element = \"t4\""
                    .into(),
            );
        }
        if self.scene.solver.kind == SolverKind::Newton && !self.measurements.is_empty() {
            return unsupported(
                "[solver] kind = \"newton\" does not fit [[measurement]] data; use kind = \
                 \"newton-krylov\" (the default) or \"dr\""
                    .into(),
            );
        }
        Ok(())
    }

    /// The scene's length unit.
    pub fn units(&self) -> Units {
        self.scene.units
    }
}

/// The element technology: the scene's, or the one the mesh's elements need.
fn element_of(sp: &Path, scene: &Scene, mesh: &Mesh) -> Result<ElementChoice, SceneError> {
    let (tets, hexes) = mesh.count_by_kind();
    let element = match (scene.mesh.element, tets, hexes) {
        (Some(e), ..) => e,
        (None, _, 0) => ElementChoice::T4anp,
        (None, 0, _) => ElementChoice::H8,
        (None, ..) => {
            return Err(SceneError::Unsupported {
                scene: sp.to_path_buf(),
                message: format!(
                    "[mesh] the mesh mixes {tets} tets and {hexes} hexes; mixed meshes are not \
                     supported by one element technology yet"
                ),
            });
        }
    };
    if let Some(e) = mesh.elements.iter().position(|e| e.kind() != element.mesh_kind()) {
        return Err(SceneError::Element {
            scene: sp.to_path_buf(),
            element_id: mesh.element_ids[e],
            message: format!(
                "[mesh] element = \"{}\" but element {} is a {}; choose the element technology \
                 that matches the mesh",
                element.name(),
                mesh.element_ids[e],
                mesh.elements[e].kind().name()
            ),
        });
    }
    Ok(element)
}

/// The region of every element: each gets exactly one.
fn regions(sp: &Path, scene: &Scene, mesh: &Mesh) -> Result<Vec<usize>, SceneError> {
    let mut region_of_element = vec![usize::MAX; mesh.elements.len()];
    for (r, region) in scene.regions.iter().enumerate() {
        let members: Vec<usize> = if region.elset == "*" {
            (0..mesh.elements.len()).collect()
        } else {
            let set = |message: String| SceneError::Set {
                scene: sp.to_path_buf(),
                key: format!("[[region]] #{} elset", r + 1),
                set: region.elset.clone(),
                message,
            };
            let members = mesh.element_set(&region.elset).ok_or_else(|| {
                set(format!(
                    "no such element set in {} (it has: {})",
                    scene.mesh.file.display(),
                    names(mesh.element_sets.keys())
                ))
            })?;
            if members.is_empty() && region.resected {
                continue; // removed by an earlier resection (a session's)
            }
            if members.is_empty() {
                return Err(set(format!(
                    "the element set is empty in {}; a region must select elements",
                    scene.mesh.file.display()
                )));
            }
            members.to_vec()
        };
        for e in members {
            if region_of_element[e] != usize::MAX && region_of_element[e] != r {
                return Err(SceneError::Element {
                    scene: sp.to_path_buf(),
                    element_id: mesh.element_ids[e],
                    message: format!(
                        "element {} is in two regions ('{}' and '{}'); regions must not overlap",
                        mesh.element_ids[e],
                        scene.regions[region_of_element[e]].elset,
                        region.elset
                    ),
                });
            }
            region_of_element[e] = r;
        }
    }
    if let Some(e) = region_of_element.iter().position(|&r| r == usize::MAX) {
        let missing = region_of_element.iter().filter(|&&r| r == usize::MAX).count();
        return Err(SceneError::Element {
            scene: sp.to_path_buf(),
            element_id: mesh.element_ids[e],
            message: format!(
                "{missing} elements have no material (e.g. element {}); add a [[region]] for \
                 their element set or use elset = \"*\"",
                mesh.element_ids[e]
            ),
        });
    }
    Ok(region_of_element)
}

/// Every `[output] surfaces` name is a non-empty element set of the mesh, named once.
fn output_surfaces(sp: &Path, scene: &Scene, mesh: &Mesh) -> Result<(), SceneError> {
    for (k, name) in scene.output.surfaces.iter().enumerate() {
        let set = |message: String| SceneError::Set {
            scene: sp.to_path_buf(),
            key: "[output] surfaces".into(),
            set: name.clone(),
            message,
        };
        if scene.output.surfaces[..k].contains(name) {
            return Err(set("named twice; list each element set once".into()));
        }
        match mesh.element_set(name) {
            None => {
                return Err(set(format!(
                    "no such element set in {}; the element sets are: {}",
                    scene.mesh.file.display(),
                    names(mesh.element_sets.keys())
                )));
            }
            Some([]) => {
                return Err(set(format!(
                    "the element set is empty in {}: it has no surface",
                    scene.mesh.file.display()
                )));
            }
            Some(_) => {}
        }
    }
    Ok(())
}

/// A prescribed displacement larger than half the brain is a unit mistake.
fn unit_sanity(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    prescribed: &[[Option<f64>; 3]],
    warnings: &mut Vec<String>,
) -> Result<(), SceneError> {
    let Some((lo, hi)) = mesh.bounding_box() else { return Ok(()) };
    let size = (hi - lo).norm();
    let biggest = prescribed
        .iter()
        .map(|p| p.iter().flatten().map(|v| v * v).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    if biggest > 0.5 * size {
        return Err(SceneError::Scene {
            file: sp.to_path_buf(),
            message: format!(
                "a prescribed displacement of {biggest:.4} {u} exceeds half the mesh size \
                 ({size:.4} {u}); check units = \"{u}\" against the mesh and the displacements",
                u = scene.units.symbol()
            ),
        });
    }
    if scene.units == Units::Mm && size < 1.0 {
        warnings.push(format!(
            "the mesh is only {size:.3} mm across; if its coordinates are in metres, set units = \
             \"m\""
        ));
    }
    Ok(())
}
