//! A live session: the pre-operative work done once (composition, contact lists, the
//! solver's preparation), then intra-operative updates, each new measurement of a
//! prescribed boundary solved warm from the last converged state and verified exactly as a
//! cold run is. An update whose prescribed values continue the last change along its line
//! (within [`SECANT_DEVIATION`]), from two states with as many nodes in contact, starts
//! from the secant predictor through them ([`history`]); any other from the linearised
//! response to the change. A failed update (a set the scene does not prescribe, a load the
//! solver cannot carry, a result that fails verification) leaves the session at its last
//! good state. Nothing here prints.

use bs_dr::{Progress, WarmStart};
use bs_mesh::Vector3;

use crate::SceneError;
use crate::boundary::Prescribed;
use crate::compose::loads_of;
use crate::measure::dispatch::solve_measured;
use crate::prepare::Prepared;
use crate::run::{Run, Solved};
use crate::verify::verify;

mod apply;
mod boundaries;
mod gravity;
mod history;
mod landmarks;
mod points;
mod resect;
mod sets;
mod uncertainty;
mod update;

use history::History;
use sets::SetLoad;
pub use update::{BoundaryValues, Update};

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
    /// The boundaries an update may give new values, resolved once.
    sets: Vec<SetLoad>,
    /// The index of the landmark measurement an update added on a boundary's node set
    /// (fitted through it), removed by the next update of boundary values.
    boundary_fit: Option<usize>,
}

impl Session {
    /// Does the pre-operative work for `prepared` (see [`Run::prepare`]).
    pub fn new(prepared: Prepared) -> Result<Session, SceneError> {
        let run = Run::prepare(prepared)?;
        let n = run.prepared.mesh.nodes.len();
        let scene_prescribed = run.prepared.prescribed.clone();
        let history = History::reference(&scene_prescribed);
        let state = vec![Vector3::zeros(); n];
        let sets = sets::resolve_sets(&run.prepared)?;
        Ok(Session { run, scene_prescribed, state, warm: false, history, sets, boundary_fit: None })
    }

    /// The prepared scene, its composition and its solver settings.
    pub fn run(&self) -> &Run {
        &self.run
    }

    /// Displacements of the last good state (zero at the reference state).
    pub fn displacements(&self) -> &[Vector3<f64>] {
        &self.state
    }

    /// The nodes (indices) of the prescribed boundary on node set `name`, in the order
    /// [`BoundaryValues::PerNode`] takes their displacements.
    pub fn set_nodes(&self, name: &str) -> Result<Vec<usize>, SceneError> {
        Ok(self.set_load(name)?.nodes.clone())
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
        // An estimate of gravity's unknowns starts from the scene's gravity each time (the
        // scan is new); when the data cannot be carried the answer is the prior's, verified
        // without the data, and the data terms come back for the next update.
        let (p, c) = (&mut run.prepared, &mut run.composed);
        let answer = solve_measured(p, c, &run.settings, from, observer)?;
        let (solution, max_penetration_before) = (answer.solution, answer.penetration);
        let (estimated, unused) = (answer.gravity, answer.unused);
        let tolerance = run.settings.tolerance;
        let kept = crate::estimate::unused_data(&mut run.composed, unused.is_some());
        let verification = verify(&run.prepared, &run.composed, &solution.displacements, tolerance);
        let verification = match verification {
            Ok(v) => v,
            Err(e) => {
                crate::estimate::restore(&mut run.composed, kept);
                return Err(e.into());
            }
        };
        let last = std::mem::replace(state, solution.displacements.clone());
        let contact = solution.report.contact.nodes_in_contact;
        history.advance(last, &run.prepared.prescribed, contact);
        *warm = true;
        let seconds = start.elapsed().as_secs_f64();
        let (p, c) = (&run.prepared, &run.composed);
        let mut solved = Solved::new(p, c, solution, max_penetration_before, verification, seconds);
        crate::estimate::restore(&mut run.composed, kept);
        if estimated.is_some() {
            solved.gravity = estimated;
        }
        solved.data_unused = unused;
        Ok(solved)
    }

    /// Writes new values of prescribed boundaries (other boundaries keep their last values)
    /// and solves warm from the last good state. On any error the session keeps its last
    /// good state and loads.
    fn update_boundaries(
        &mut self,
        values: &[(&str, &BoundaryValues)],
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solved, SceneError> {
        let prescribed = self.resolve(values)?;
        let dropped = self.drop_boundary_fit();
        let previous = match self.set_loads(prescribed) {
            Ok(previous) => previous,
            Err(e) => {
                self.restore_boundary_fit(dropped);
                return Err(e);
            }
        };
        match self.solve(observer) {
            Ok(solved) => Ok(solved),
            Err(e) => {
                self.set_loads(previous).expect("the previous loads were accepted before");
                self.restore_boundary_fit(dropped);
                Err(e)
            }
        }
    }

    /// The node sets of the scene's boundaries that prescribe displacements (the keys of
    /// [`Update::Boundary`]), in scene order.
    pub fn prescribed_sets(&self) -> Vec<&str> {
        self.sets.iter().map(|s| s.name.as_str()).collect()
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
