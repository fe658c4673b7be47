//! Composition: a prepared scene becomes a solver model, loads and a contact handler. This
//! and [`crate::skull_contact`] are the only places that know both `bs-dr` and
//! `bs-contact`.

use std::sync::Arc;

use bs_contact::{Enforcer, Handler, MasterSurface, PaperParams, ParryContact};
use bs_dr::{Loads, Model, ModelOptions, Solid};
use bs_material::{Elastic, Material, OgdenParams};

use crate::SceneError;
use crate::boundary::Prescribed;
use crate::prepare::Prepared;
use crate::scene::MaterialModel;
use crate::skull_contact::SkullContact;

/// Everything a solver run needs.
#[derive(Debug)]
pub struct Composed {
    /// The finite-element model.
    pub model: Model,
    /// Fixed and prescribed displacements, and the body force's nodal loads.
    pub loads: Loads,
    /// The nodal loads of the scene's gravity (empty without), kept for the loads of
    /// updates.
    pub body: Vec<bs_mesh::Vector3<f64>>,
    /// Slave nodes: boundary nodes of the brain without prescribed components.
    pub slaves: Vec<usize>,
    /// The skull's precomputed surface (for gap checks), if the scene has contact.
    pub master: Option<Arc<MasterSurface>>,
    /// Exact closest points on the skull at any distance (the initial and final checks, and
    /// the Newton–Krylov solver's queries), if the scene has contact.
    pub exact: Option<Arc<ParryContact>>,
    /// The contact handler, if the scene has contact.
    pub contact: Option<SkullContact>,
    /// The length by which solver tolerances are scaled (largest prescribed displacement
    /// component, or the mesh diagonal without loads): bs-dr's tolerances are relative.
    pub load_scale: f64,
    /// The measurements' data terms (fitted with the model), if the scene has any.
    pub fit: Option<crate::measure::FitState>,
    /// The Newton–Krylov solver's preparation (its preconditioner), once computed
    /// (`solve::prepare_solver`); it depends only on the model and which components
    /// are prescribed, so it is kept for every solve of this composition.
    pub preparation: Option<bs_dr::Preparation>,
}

/// The bs-material law of a scene material, built from its shear and bulk moduli (the scene
/// resolves (E, ν) to (μ, κ) once; nothing converts back).
pub fn material(m: &crate::scene::Material) -> Result<Material, String> {
    let moduli = m.moduli()?;
    let (mu, kappa) = (moduli.mu, moduli.kappa);
    let law = match m.model {
        MaterialModel::NeoHookean => Elastic::from_mu_kappa(mu, kappa).map(Material::NeoHookean),
        MaterialModel::Svk => {
            Elastic::from_mu_kappa(mu, kappa).map(|e| Material::StVenantKirchhoff(e.into()))
        }
        MaterialModel::Ogden => {
            let alpha = m.alpha.ok_or("ogden needs alpha")?;
            OgdenParams::new(mu, alpha, kappa).map(Material::Ogden)
        }
    };
    law.map_err(|e| e.to_string())
}

/// Settings of the composition that scene files do not expose: studies vary them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComposeOptions {
    /// Hourglass stiffness coefficient of H8 elements (bs-dr's default 0.1; 0 switches the
    /// control off).
    pub hourglass: f64,
    /// Parameters of the paper's contact handlers (additional lists on by default).
    pub contact: PaperParams,
}

impl Default for ComposeOptions {
    fn default() -> Self {
        ComposeOptions {
            hourglass: ModelOptions::default().hourglass,
            contact: PaperParams::default(),
        }
    }
}

/// Builds model, loads and contact from a checked scene.
pub fn compose(p: &Prepared) -> Result<Composed, SceneError> {
    compose_with(p, &ComposeOptions::default())
}

/// [`compose`] with explicit [`ComposeOptions`].
pub fn compose_with(p: &Prepared, opts: &ComposeOptions) -> Result<Composed, SceneError> {
    let solids = p
        .scene
        .regions
        .iter()
        .map(|r| {
            material(&r.material)
                .map(|material| Solid { material, density: r.material.density_or_default() })
                .map_err(|e| SceneError::Scene {
                    file: p.path.clone(),
                    message: format!("[[region]] elset '{}': material: {e}", r.elset),
                })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let options = ModelOptions { tet: p.element.tet_formulation(), hourglass: opts.hourglass };
    let model = Model::new(&p.mesh, &solids, &p.region_of_element, options).map_err(|e| {
        SceneError::Mesh { file: p.scene.mesh.file.clone(), count: 1, first: e.to_string() }
    })?;

    let body = dead_loads(p, &model, p.scene.gravity.as_ref())?;
    let loads = loads_of(p, &p.prescribed, &body)?;
    let fit = crate::measure::terms::compose_fits(p)?;
    let load_scale = scale_of(&model, &loads, fit.as_ref());

    let slaves: Vec<usize> = p
        .mesh
        .boundary()
        .volume_node
        .into_iter()
        .filter(|&n| p.prescribed[n].iter().all(Option::is_none))
        .collect();

    let (master, contact, exact) = match (&p.skull, &p.scene.contact) {
        (Some(skull), Some(c)) => {
            let skull_error = |e: &dyn std::fmt::Display| SceneError::Skull {
                scene: p.path.clone(),
                skull: c.skull.clone(),
                message: e.to_string(),
            };
            // One validated master surface per run, shared by the handler and the exact
            // projection.
            let master = Arc::new(MasterSurface::new(skull).map_err(|e| skull_error(&e))?);
            let handler = Handler::from_master(c.algorithm, master.clone(), opts.contact)
                .map_err(|e| skull_error(&e))?;
            let enforcer = Enforcer::new(handler, slaves.clone(), model.node_count())
                .map_err(|e| skull_error(&e))?;
            let exact =
                Arc::new(ParryContact::from_master(master.clone()).map_err(|e| skull_error(&e))?);
            (
                Some(master),
                Some(SkullContact { enforcer, exact: exact.clone(), elapsed: Default::default() }),
                Some(exact),
            )
        }
        _ => (None, None, None),
    };
    Ok(Composed {
        model,
        loads,
        body,
        slaves,
        master,
        exact,
        contact,
        load_scale,
        fit,
        preparation: None,
    })
}

/// The length by which tolerances are scaled: the largest prescribed displacement, or, when
/// nothing prescribed moves and measurements pull, how far they pull (the largest matched
/// residual at composition), else the mesh diagonal.
pub fn scale_of(model: &Model, loads: &Loads, fit: Option<&crate::measure::FitState>) -> f64 {
    match fit {
        Some(f) if loads.max_prescribed() == 0.0 && f.reach > 0.0 => f.reach,
        _ => bs_dr::load_scale(model, loads),
    }
}

/// The dead nodal loads of `p` on `model`: `gravity`'s weight (the scene's, or a session's
/// turned one) and the resected cavities' pressures (empty: none).
pub fn dead_loads(
    p: &Prepared,
    model: &Model,
    gravity: Option<&crate::scene::Gravity>,
) -> Result<Vec<bs_mesh::Vector3<f64>>, SceneError> {
    let mut f = match gravity {
        Some(g) => crate::gravity::nodal_loads_with(p, model, g)?,
        None => Vec::new(),
    };
    if let Some(r) = &p.resection
        && r.walls.iter().any(|w| w.1 != 0.0)
    {
        f.resize(p.mesh.nodes.len(), bs_mesh::Vector3::zeros());
        r.add_pressure_loads(&p.mesh, &mut f);
    }
    Ok(f)
}

/// The solver's loads for the per-node prescribed components `prescribed` of the mesh of
/// `p` (the scene's own, or those of an update) and the nodal loads `body` of a body force
/// (empty: none).
pub fn loads_of(
    p: &Prepared,
    prescribed: &Prescribed,
    body: &[bs_mesh::Vector3<f64>],
) -> Result<Loads, SceneError> {
    let mut loads = Loads::new(p.mesh.nodes.len());
    if !body.is_empty() {
        loads.set_forces(body.to_vec()).map_err(|e| SceneError::Scene {
            file: p.path.clone(),
            message: format!("[gravity]: {e}"),
        })?;
    }
    for (n, comps) in prescribed.iter().enumerate() {
        for (c, v) in comps.iter().enumerate() {
            let result = match v {
                Some(v) => loads.prescribe(n, c, *v),
                None => Ok(()),
            };
            result.map_err(|e| SceneError::Node {
                scene: p.path.clone(),
                node_id: p.mesh.node_ids[n],
                message: e.to_string(),
            })?;
        }
    }
    Ok(loads)
}
