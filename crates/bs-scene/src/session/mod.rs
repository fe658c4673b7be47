//! A live session: the pre-operative work done once (composition, contact lists, the
//! solver's preparation), then intra-operative updates, each new measurement of a
//! prescribed boundary solved warm from the last converged state and verified exactly as a
//! cold run is. An update whose prescribed values continue the last change along its line
//! (within [`SECANT_DEVIATION`]), from two states with as many nodes in contact, starts
//! from the secant predictor through them ([`history`]); any other from the linearised
//! response to the change. A failed update (a set the scene does not prescribe, a load the
//! solver cannot carry, a result that fails verification) leaves the session at its last
//! good state. Nothing here prints.

use std::path::PathBuf;

use bs_dr::{Progress, WarmStart};
use bs_mesh::Vector3;

use crate::SceneError;
use crate::boundary::{Prescribed, resolve_boundaries, select_nodes};
use crate::compose::loads_of;
use crate::prepare::Prepared;
use crate::run::{Run, Solved};
use crate::scene::{Boundary, Displacement, Scene};
use crate::solve::solve_composed_from;
use crate::verify::verify;

mod gravity;
mod history;
mod landmarks;
mod points;
mod resect;

use history::History;
pub use history::{SECANT_DEVIATION, secant_ratio};

/// A new measurement of one prescribed boundary, named by its node set.
#[derive(Debug, Clone, PartialEq)]
pub enum BoundaryLoad {
    /// The same displacement for every node of the set (mesh frame and units); only the
    /// components the boundary prescribes may be non-zero.
    Uniform(Vector3<f64>),
    /// One displacement per node, in the order of [`Session::set_nodes`].
    PerNode(Vec<Vector3<f64>>),
    /// An intra-operative surface (.stl, .obj, .off): each node moves to its closest point.
    Surface(PathBuf),
    /// A CSV of landmark pairs `x,y,z,x2,y2,z2`: the nodes move by their thin-plate spline.
    Landmarks(PathBuf),
}

/// The pre-operative state and the last good intra-operative one.
#[derive(Debug)]
pub struct Session {
    run: Run,
    /// The scene's own prescribed components (what [`Session::reset`] returns to).
    scene_prescribed: Prescribed,
    /// Displacements of the last converged update (zero before the first, after a reset).
    state: Vec<Vector3<f64>>,
    warm: bool,
    /// The prescribed values `state` converged at, and the state before it.
    history: History,
}

impl Session {
    /// Does the pre-operative work for `prepared` (see [`Run::prepare`]).
    pub fn new(prepared: Prepared) -> Result<Session, SceneError> {
        let run = Run::prepare(prepared)?;
        let n = run.prepared.mesh.nodes.len();
        let scene_prescribed = run.prepared.prescribed.clone();
        let history = History::reference(&scene_prescribed);
        let state = vec![Vector3::zeros(); n];
        Ok(Session { run, scene_prescribed, state, warm: false, history })
    }

    /// The prepared scene, its composition and its solver settings.
    pub fn run(&self) -> &Run {
        &self.run
    }

    /// Displacements of the last good state (zero at the reference state).
    pub fn displacements(&self) -> &[Vector3<f64>] {
        &self.state
    }

    /// The nodes (indices) of the node set `name`, in the order [`BoundaryLoad::PerNode`]
    /// takes their displacements.
    pub fn set_nodes(&self, name: &str) -> Result<Vec<usize>, SceneError> {
        let (i, b) = self.boundary(name)?;
        let p = &self.run.prepared;
        select_nodes(&p.path, &p.scene, &p.mesh, i, b).map(|(_, nodes)| nodes)
    }

    /// Back to the reference state and the scene's own boundary values (a turned gravity
    /// and resected regions stay as they are: the head and the cavity do not come back).
    pub fn reset(&mut self) {
        self.state.iter_mut().for_each(|u| *u = Vector3::zeros());
        self.warm = false;
        self.history = History::reference(&self.scene_prescribed);
        let p = self.scene_prescribed.clone();
        // The scene's own loads were accepted when the session was made.
        let _ = self.set_loads(p);
    }

    /// Solves the loads now set (the scene's own at first) from the last good state.
    pub fn solve(&mut self, observer: &mut dyn FnMut(&Progress)) -> Result<Solved, SceneError> {
        let start = std::time::Instant::now();
        let Session { run, state, warm, history, .. } = self;
        let secant = history.secant(&run.prepared.prescribed);
        let from = warm.then_some(WarmStart { state, secant });
        let (solution, max_penetration_before) = if crate::inverse::has_landmarks(&run.prepared) {
            let warm = from.map(|w| w.state);
            let (p, c) = (&mut run.prepared, &mut run.composed);
            let (s, pen, _) = crate::inverse::solve(p, c, &run.settings, warm, observer)?;
            (s, pen)
        } else {
            solve_composed_from(&mut run.composed, &run.settings, from, observer)
                .map_err(|e| crate::imposed::explain(run.prepared.imposed(), e))?
        };
        let tolerance = run.settings.tolerance;
        let verification =
            verify(&run.prepared, &run.composed, &solution.displacements, tolerance)?;
        let last = std::mem::replace(state, solution.displacements.clone());
        let contact = solution.report.contact.nodes_in_contact;
        history.advance(last, &run.prepared.prescribed, contact);
        *warm = true;
        let seconds = start.elapsed().as_secs_f64();
        let (p, c) = (&run.prepared, &run.composed);
        Ok(Solved::new(p, c, solution, max_penetration_before, verification, seconds))
    }

    /// Sets the new measurements `loads` (other prescribed boundaries keep their last
    /// values) and solves warm from the last good state. On any error the session keeps
    /// its last good state and loads.
    pub fn update(
        &mut self,
        loads: &[(String, BoundaryLoad)],
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solved, SceneError> {
        let prescribed = self.resolve(loads)?;
        let previous = self.set_loads(prescribed)?;
        match self.solve(observer) {
            Ok(solved) => Ok(solved),
            Err(e) => {
                self.set_loads(previous).expect("the previous loads were accepted before");
                Err(e)
            }
        }
    }

    /// The node sets of the scene's boundaries that prescribe displacements (the keys
    /// [`Session::update`] takes), in scene order.
    pub fn prescribed_sets(&self) -> Vec<&str> {
        let p = &self.run.prepared;
        p.scene.boundaries.iter().filter(|b| moves(b)).filter_map(|b| b.nset.as_deref()).collect()
    }

    /// The boundary whose node set is `name` and that prescribes displacements.
    fn boundary(&self, name: &str) -> Result<(usize, &Boundary), SceneError> {
        let p = &self.run.prepared;
        p.scene
            .boundaries
            .iter()
            .enumerate()
            .find(|(_, b)| b.nset.as_deref() == Some(name) && moves(b))
            .ok_or_else(|| {
                let known = self.prescribed_sets();
                SceneError::Set {
                    scene: p.path.clone(),
                    key: "update".into(),
                    set: name.into(),
                    message: format!(
                        "no [[boundary]] with this nset prescribes displacements; the scene's \
                         prescribed node sets are: {}",
                        if known.is_empty() { "none".into() } else { known.join(", ") }
                    ),
                }
            })
    }

    /// The per-node prescribed components with `loads` applied to the current ones: each
    /// updated boundary resolved on its own (its nodes and components take the new
    /// values), every other component keeps its last value.
    fn resolve(&self, loads: &[(String, BoundaryLoad)]) -> Result<Prescribed, SceneError> {
        let p = &self.run.prepared;
        let mut prescribed = p.prescribed.clone();
        for (name, load) in loads {
            let (i, original) = self.boundary(name)?;
            let cleared = Boundary {
                displacement: None,
                displacement_file: None,
                surface: None,
                landmarks: None,
                ..original.clone()
            };
            let b = match load {
                BoundaryLoad::Uniform(v) => {
                    Boundary { displacement: Some(uniform(p, name, original, v)?), ..cleared }
                }
                BoundaryLoad::Surface(f) => Boundary { surface: Some(f.clone()), ..cleared },
                BoundaryLoad::Landmarks(f) => Boundary { landmarks: Some(f.clone()), ..cleared },
                BoundaryLoad::PerNode(_) => original.clone(),
            };
            let single = Scene { boundaries: vec![b], ..p.scene.clone() };
            let mut values =
                resolve_boundaries(&p.path, &single, &p.mesh).map_err(|e| renumber(e, i))?;
            if let BoundaryLoad::PerNode(v) = load {
                let (_, nodes) = select_nodes(&p.path, &single, &p.mesh, 0, &single.boundaries[0])
                    .map_err(|e| renumber(e, i))?;
                per_node_values(p, name, &nodes, v, &mut values)?;
            }
            for (now, new) in prescribed.iter_mut().zip(&values) {
                for c in 0..3 {
                    if new[c].is_some() {
                        now[c] = new[c];
                    }
                }
            }
        }
        Ok(prescribed)
    }

    /// Makes `prescribed` the loads of the next solve; returns the loads it replaces.
    /// Refused when it prescribes other components than the scene (the solver's
    /// preparation is for the scene's).
    fn set_loads(&mut self, prescribed: Prescribed) -> Result<Prescribed, SceneError> {
        let p = &self.run.prepared;
        if let Some(n) = (0..prescribed.len()).find(|&n| {
            (0..3).any(|c| prescribed[n][c].is_some() != self.scene_prescribed[n][c].is_some())
        }) {
            return Err(SceneError::Node {
                scene: p.path.clone(),
                node_id: p.mesh.node_ids[n],
                message: "the update prescribes other components of this node than the scene \
                          does; an update may change the values of the prescribed boundaries, \
                          not which nodes and components they hold"
                    .into(),
            });
        }
        let loads = loads_of(p, &prescribed, &self.run.composed.body)?;
        let c = &mut self.run.composed;
        c.load_scale = crate::compose::scale_of(&c.model, &loads, c.fit.as_ref());
        c.loads = loads;
        Ok(std::mem::replace(&mut self.run.prepared.prescribed, prescribed))
    }
}

/// The kinds of `[[measurement]]` a session takes new data for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MeasuredKind {
    /// A scanned surface (`update points`).
    Surface,
    /// Landmark pairs (`update landmarks`).
    Landmarks,
}

impl MeasuredKind {
    fn is(self, data: &crate::measure::MeasuredData) -> bool {
        use crate::measure::MeasuredData;
        match self {
            MeasuredKind::Surface => matches!(data, MeasuredData::Surface { .. }),
            MeasuredKind::Landmarks => matches!(data, MeasuredData::Landmarks { .. }),
        }
    }

    /// The update's key in messages, and the data's name.
    fn words(self) -> (&'static str, &'static str, &'static str) {
        match self {
            MeasuredKind::Surface => ("update points", "points", "scanned"),
            MeasuredKind::Landmarks => ("update landmarks", "landmarks", "landmark"),
        }
    }
}

impl Session {
    /// The node sets of the scene's measurements of `kind`, in scene order.
    fn sets_of(&self, kind: MeasuredKind) -> Vec<&str> {
        let p = &self.run.prepared;
        p.measurements.iter().filter(|m| kind.is(&m.data)).map(|m| m.nset.as_str()).collect()
    }

    /// The index of the measurement of `kind` on node set `name`; an error listing the sets
    /// there are.
    fn measurement_of(&self, kind: MeasuredKind, name: &str) -> Result<usize, SceneError> {
        let p = &self.run.prepared;
        p.measurements.iter().position(|m| m.nset == name && kind.is(&m.data)).ok_or_else(|| {
            let known = self.sets_of(kind);
            let (key, data, adjective) = kind.words();
            SceneError::Set {
                scene: p.path.clone(),
                key: key.into(),
                set: name.into(),
                message: format!(
                    "no [[measurement]] with {data} on this node set; the scene's {adjective} \
                     node sets are: {}",
                    if known.is_empty() { "none".into() } else { known.join(", ") }
                ),
            }
        })
    }
}

/// Whether the boundary prescribes (possibly non-zero) displacements rather than fixing.
fn moves(b: &Boundary) -> bool {
    b.displacement.is_some()
        || b.displacement_file.is_some()
        || b.surface.is_some()
        || b.landmarks.is_some()
}

/// An error about the one boundary of a single-boundary scene, keyed as the scene's
/// `[[boundary]]` number `i + 1`.
fn renumber(e: SceneError, i: usize) -> SceneError {
    let fix = |key: String| key.replacen("[[boundary]] #1", &format!("[[boundary]] #{}", i + 1), 1);
    match e {
        SceneError::Read { scene, key, message } => {
            SceneError::Read { scene, key: fix(key), message }
        }
        SceneError::Set { scene, key, set, message } => {
            SceneError::Set { scene, key: fix(key), set, message }
        }
        e => e,
    }
}

/// The uniform displacement `v` for the boundary `b` named `name`: its prescribed
/// components (all three for a measured surface or landmarks).
fn uniform(
    p: &Prepared,
    name: &str,
    b: &Boundary,
    v: &Vector3<f64>,
) -> Result<Displacement, SceneError> {
    let held = match &b.displacement {
        Some(d) => d.components().map(|c| c.is_some()),
        None => [true; 3],
    };
    let value = |c: usize| -> Result<Option<f64>, SceneError> {
        let x = v[c];
        if !x.is_finite() || (!held[c] && x != 0.0) {
            return Err(SceneError::Set {
                scene: p.path.clone(),
                key: "update".into(),
                set: name.into(),
                message: format!(
                    "component {} = {x}: {}",
                    ["x", "y", "z"][c],
                    if x.is_finite() {
                        "the boundary leaves this component free; give 0 for it"
                    } else {
                        "a displacement must be a finite number"
                    }
                ),
            });
        }
        Ok(held[c].then_some(x))
    };
    Ok(Displacement { x: value(0)?, y: value(1)?, z: value(2)? })
}

/// Writes one displacement per node of `nodes` into `prescribed` (the components the
/// boundary prescribes).
fn per_node_values(
    p: &Prepared,
    name: &str,
    nodes: &[usize],
    values: &[Vector3<f64>],
    prescribed: &mut Prescribed,
) -> Result<(), SceneError> {
    let err = |message: String| SceneError::Set {
        scene: p.path.clone(),
        key: "update".into(),
        set: name.into(),
        message,
    };
    if values.len() != nodes.len() {
        return Err(err(format!(
            "{} displacements for {} nodes; give one (dx, dy, dz) per node of the set",
            values.len(),
            nodes.len()
        )));
    }
    for (k, (&n, v)) in nodes.iter().zip(values).enumerate() {
        if !v.iter().all(|x| x.is_finite()) {
            return Err(err(format!("row {k} (node {}) is not finite", p.mesh.node_ids[n])));
        }
        for c in 0..3 {
            if prescribed[n][c].is_some() {
                prescribed[n][c] = Some(v[c]);
            }
        }
    }
    Ok(())
}
