//! Composition: a checked scene becomes a solver model, loads and a contact handler. This is
//! the only place that knows both `bs-dr` and `bs-contact`; the adapter [`SkullContact`]
//! bridges bs-contact's enforcement loop to bs-dr's `Contact` trait.

use std::sync::Arc;

use bs_contact::{
    ClosestPoint, Enforcer, Feature, Handler, MasterSurface, PaperParams, ParryContact,
};
use bs_dr::{
    ContactProjection, ContactReport, Loads, Model, ModelOptions, Solid, SurfaceFeature,
    TetFormulation,
};
use bs_material::{Material, OgdenParams};

use crate::check::{CheckError, Prepared};
use crate::scene::{Algorithm, ElementChoice, MaterialModel};

/// bs-contact's enforcement loop seen through bs-dr's contact seam; it also keeps the time
/// spent in contact so a run can report its share.
#[derive(Debug)]
pub struct SkullContact {
    enforcer: Enforcer<Handler>,
    /// Exact closest points at any distance (parry's BVH and the exact point–triangle
    /// projection), for the Newton–Krylov solver's queries beyond the handler's reach.
    exact: Arc<ParryContact>,
    /// Wall time spent enforcing contact so far.
    pub elapsed: std::time::Duration,
}

impl bs_dr::Contact for SkullContact {
    fn enforce(&mut self, positions: &mut [bs_mesh::Point3<f64>]) -> ContactReport {
        let start = std::time::Instant::now();
        let r = self.enforcer.enforce(positions);
        self.elapsed += start.elapsed();
        ContactReport { nodes_in_contact: r.nodes_in_contact, max_penetration: r.max_penetration }
    }

    fn nodes(&self) -> &[usize] {
        self.enforcer.slaves()
    }

    fn project(&mut self, k: usize, p: &bs_mesh::Point3<f64>) -> Option<ContactProjection> {
        let start = std::time::Instant::now();
        // The handler's own search first: it certifies most points inside at no cost and is
        // exact within its reach; beyond it, the exact projection.
        let handler = self.enforcer.handler_mut();
        let reach = handler.reach();
        let fast = handler.closest(k, p);
        let proj = match fast {
            None if p.coords.iter().all(|x| x.is_finite()) => {
                self.elapsed += start.elapsed();
                return Some(ContactProjection {
                    point: *p,
                    outside: false,
                    feature: SurfaceFeature::Vertex,
                });
            }
            Some(proj) if proj.signed_distance.abs() <= reach && proj.feature.is_some() => {
                Some(proj)
            }
            _ => self.exact.project_exact(p),
        };
        let master = self.exact.master();
        let result = proj.and_then(|proj| {
            let feature = match proj.feature? {
                Feature::Face(f) => SurfaceFeature::Face(master.face_normals()[f as usize]),
                Feature::Edge(e) => {
                    let [a, b] = master.edges()[e as usize];
                    let t = master.vertices()[b as usize] - master.vertices()[a as usize];
                    SurfaceFeature::Edge(t.normalize())
                }
                Feature::Node(_) => SurfaceFeature::Vertex,
            };
            Some(ContactProjection { point: proj.point, outside: proj.outside, feature })
        });
        self.elapsed += start.elapsed();
        result
    }
}

/// Everything a solver run needs.
#[derive(Debug)]
pub struct Composed {
    /// The finite-element model.
    pub model: Model,
    /// Fixed and prescribed displacements.
    pub loads: Loads,
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
    /// The Newton–Krylov solver's preparation (its preconditioner), once computed
    /// ([`crate::study::prepare_solver`]); it depends only on the model and which components
    /// are prescribed, so it is kept for every solve of this composition.
    pub preparation: Option<bs_dr::Preparation>,
}

/// The bs-material law of a scene material.
pub fn material(m: &crate::scene::Material) -> Result<Material, String> {
    let moduli = m.moduli()?;
    let (mu, kappa) = (moduli.mu, moduli.kappa);
    // E and ν from μ and κ (exact inverse of the scene's conversion).
    let young = 9.0 * kappa * mu / (3.0 * kappa + mu);
    let poisson = (3.0 * kappa - 2.0 * mu) / (2.0 * (3.0 * kappa + mu));
    let law = match m.model {
        MaterialModel::NeoHookean => Material::neo_hookean(young, poisson),
        MaterialModel::Svk => Material::st_venant_kirchhoff(young, poisson),
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
pub fn compose(p: &Prepared) -> Result<Composed, CheckError> {
    compose_with(p, &ComposeOptions::default())
}

/// [`compose`] with explicit [`ComposeOptions`].
pub fn compose_with(p: &Prepared, opts: &ComposeOptions) -> Result<Composed, CheckError> {
    let solids = p
        .scene
        .regions
        .iter()
        .map(|r| {
            material(&r.material)
                .map(|material| Solid { material, density: r.material.density })
                .map_err(|e| CheckError(format!("region '{}': {e}", r.elset)))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let tet = match p.element {
        ElementChoice::T4 => TetFormulation::T4,
        ElementChoice::T4anp | ElementChoice::H8 => TetFormulation::T4Anp,
    };
    let options = ModelOptions { tet, hourglass: opts.hourglass };
    let model = Model::new(&p.mesh, &solids, &p.region_of_element, options)
        .map_err(|e| CheckError(format!("{}: {e}", p.scene.mesh.file.display())))?;

    let mut loads = Loads::new(model.node_count());
    for (n, comps) in p.prescribed.iter().enumerate() {
        for (c, v) in comps.iter().enumerate() {
            let result = match v {
                Some(v) if *v == 0.0 => loads.fix(n, c),
                Some(v) => loads.prescribe(n, c, *v),
                None => Ok(()),
            };
            result.map_err(|e| CheckError(format!("node {}: {e}", p.mesh.node_ids[n])))?;
        }
    }
    let load_scale = bs_dr::load_scale(&model, &loads);

    let slaves: Vec<usize> = p
        .mesh
        .boundary()
        .volume_node
        .into_iter()
        .filter(|&n| p.prescribed[n].iter().all(Option::is_none))
        .collect();

    let (master, contact, exact) = match (&p.skull, &p.scene.contact) {
        (Some(skull), Some(c)) => {
            // One validated master surface per run, shared by the handler and the exact
            // projection.
            let master = Arc::new(
                MasterSurface::new(skull)
                    .map_err(|e| CheckError(format!("{}: {e}", c.skull.display())))?,
            );
            let handler =
                Handler::from_master(algorithm(c.algorithm), master.clone(), opts.contact)
                    .map_err(|e| CheckError(format!("{}: {e}", c.skull.display())))?;
            let enforcer = Enforcer::new(handler, slaves.clone(), model.node_count())
                .map_err(|e| CheckError(e.to_string()))?;
            let exact = Arc::new(
                ParryContact::from_master(master.clone())
                    .map_err(|e| CheckError(format!("{}: {e}", c.skull.display())))?,
            );
            (
                Some(master),
                Some(SkullContact { enforcer, exact: exact.clone(), elapsed: Default::default() }),
                Some(exact),
            )
        }
        _ => (None, None, None),
    };
    Ok(Composed { model, loads, slaves, master, exact, contact, load_scale, preparation: None })
}

/// The bs-contact algorithm named by a scene.
pub fn algorithm(a: Algorithm) -> bs_contact::Algorithm {
    match a {
        Algorithm::Paper => bs_contact::Algorithm::Paper,
        Algorithm::Coherent => bs_contact::Algorithm::Coherent,
        Algorithm::Parry => bs_contact::Algorithm::Parry,
        Algorithm::BruteForce => bs_contact::Algorithm::BruteForce,
    }
}

impl Composed {
    /// Slave nodes outside the skull in the reference configuration: an error listing their
    /// ids and distances (a run would snap them onto the skull at the first step).
    pub fn check_initial_gap(&self, p: &Prepared) -> Result<Option<(f64, f64)>, CheckError> {
        let Some(exact) = &self.exact else { return Ok(None) };
        // Exact distances (parry's BVH and the exact point–triangle projection, equal to
        // brute force at any distance: bs-contact's tests).
        let rows = exact_gaps(exact, self.slaves.iter().map(|&n| p.mesh.nodes[n]));
        let outside: Vec<(usize, f64)> = rows
            .iter()
            .zip(&self.slaves)
            .filter(|(r, _)| r.outside)
            .map(|(r, &n)| (n, -r.signed_distance))
            .collect();
        if !outside.is_empty() {
            let list: Vec<String> = outside
                .iter()
                .take(10)
                .map(|&(n, d)| format!("node {} ({d:.4} outside)", p.mesh.node_ids[n]))
                .collect();
            return Err(CheckError(format!(
                "{} brain surface nodes are outside the skull before any load: {}{}; the brain \
                 must start inside the skull cavity (check the skull file, its units and its \
                 registration to the mesh)",
                outside.len(),
                list.join(", "),
                if outside.len() > 10 { ", ..." } else { "" }
            )));
        }
        let min = rows.iter().map(|r| r.signed_distance).fold(f64::INFINITY, f64::min);
        let max = rows.iter().map(|r| r.signed_distance).fold(f64::NEG_INFINITY, f64::max);
        Ok(Some((min, max)))
    }
}

/// Exact signed distances of `points` to the skull (see [`ParryContact::project_exact`]).
pub fn exact_gaps(
    exact: &ParryContact,
    points: impl Iterator<Item = bs_mesh::Point3<f64>>,
) -> Vec<bs_contact::GapRow> {
    points
        .map(|q| match exact.project_exact(&q) {
            Some(pr) => bs_contact::GapRow {
                signed_distance: pr.signed_distance,
                closest: pr.point,
                outside: pr.outside,
            },
            None => {
                bs_contact::GapRow { signed_distance: f64::NEG_INFINITY, closest: q, outside: true }
            }
        })
        .collect()
}
