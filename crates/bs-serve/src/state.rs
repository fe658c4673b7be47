//! The server's state: the live session of the scene and the pre-operative image, read
//! once, with what every message needs to know of them. Updates are solved one at a time
//! (the session's lock); the image's pre-operative gap (what fills the space between brain
//! and skull) is computed once and reused by every update on the same reference mesh and
//! skull.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use bs_image::Volume;
use bs_register::registration::{InverseMap, RunResult};
use bs_scene::output::{RunContext, RunReport, report};
use bs_scene::{Prepared, Progress, Session, Update};

use crate::frame::Frame;
use crate::log::Log;
use crate::measure::Offer;
use crate::options::Options;

/// The pre-operative gap mask of an image for one reference configuration (its key).
type Gap = Arc<Option<Vec<bool>>>;

/// An update solved and verified: what the replies are made of.
#[derive(Debug)]
pub struct Solution {
    /// The result as the registration reads it (mesh, displacements, frame, unit, skull).
    pub result: RunResult,
    /// The run's report (report.json's keys).
    pub report: RunReport,
    /// The deformed boundary: points (scene frame and unit) and triangles.
    pub surface: bs_mesh::BoundarySurface,
    /// Seconds from the message to the verified answer.
    pub solve_seconds: f64,
    /// Total σ per node (mm), with `--uncertainty`.
    pub sigma: Option<Vec<f64>>,
}

/// The session, the image and the scene's names (see the module documentation).
#[derive(Debug)]
pub struct Brainshift {
    session: Mutex<Session>,
    /// The pre-operative image (float32 on its grid, world RAS mm).
    pub image: Volume<f32>,
    image_path: PathBuf,
    gap: Mutex<Option<(u64, Gap)>>,
    /// The scene's frame against RAS mm.
    pub frame: Frame,
    /// The prescribed node set measurements move.
    pub set: Option<String>,
    set_ids: Vec<u64>,
    pool: rayon::ThreadPool,
    /// `--uncertainty`'s samples.
    uncertainty: Option<usize>,
    verbose: bool,
    log: Log,
    /// Seconds the preparation took.
    pub prepare_seconds: f64,
}

impl Brainshift {
    /// Prepares the scene's session and reads the image; refuses a `--set` the scene does
    /// not prescribe, or none when it prescribes several.
    pub fn new(o: &Options, log: Log) -> Result<Brainshift, String> {
        let started = Instant::now();
        let mut pool = rayon::ThreadPoolBuilder::new();
        if let Some(n) = o.threads {
            pool = pool.num_threads(n.max(1));
        }
        let pool = pool.build().map_err(|e| format!("--threads: {e}"))?;
        let prepared = Prepared::load(&o.scene).map_err(|e| e.to_string())?;
        let frame = Frame::new(prepared.scene.space, prepared.scene.units);
        let session = pool.install(|| Session::new(prepared)).map_err(|e| e.to_string())?;
        if let Some(n) = o.uncertainty {
            if n < 2 {
                return Err(format!(
                    "--uncertainty {n}: give at least 2 samples (32 give σ to about 13 %)"
                ));
            }
            bs_scene::uncertainty::check(session.run()).map_err(|e| e.to_string())?;
        }
        let (image, _) = bs_image::formats::read_image(&o.image).map_err(|e| e.to_string())?;
        let set = choose_set(&session, o)?;
        let set_ids = match &set {
            Some(s) => {
                let ids = &session.run().prepared.mesh.node_ids;
                session.set_nodes(s).map_err(|e| e.to_string())?.iter().map(|&n| ids[n]).collect()
            }
            None => Vec::new(),
        };
        Ok(Brainshift {
            session: Mutex::new(session),
            image,
            image_path: o.image.clone(),
            gap: Mutex::new(None),
            frame,
            set,
            set_ids,
            pool,
            uncertainty: o.uncertainty,
            verbose: o.verbose,
            log,
            prepare_seconds: started.elapsed().as_secs_f64(),
        })
    }

    /// Nodes of the prescribed set.
    pub fn set_size(&self) -> usize {
        self.set_ids.len()
    }

    /// What the session offers messages now.
    pub fn offer(&self) -> Offer {
        let s = self.session.lock().unwrap_or_else(|e| e.into_inner());
        Offer {
            frame: self.frame,
            set: self.set.clone(),
            set_ids: self.set_ids.clone(),
            measured: s.measured_sets().into_iter().map(str::to_string).collect(),
            regions: s.regions().into_iter().map(str::to_string).collect(),
            gravity: s.gravity_direction().is_some(),
        }
    }

    /// Solves `updates` warm from the last good state (one update at a time); on an error
    /// the session keeps its last good state and the text says why.
    pub fn solve(&self, updates: &[Update]) -> Result<Solution, String> {
        let started = Instant::now();
        let log = self.log.clone();
        let verbose = self.verbose;
        self.pool.install(|| {
            let mut s = self.session.lock().unwrap_or_else(|e| e.into_inner());
            let mut observe = |p: &Progress| {
                if verbose {
                    log.line(&format!(
                        "    iteration {}: load {:.3}, error estimate {:.2e}, max displacement \
                         {:.3}, {} nodes in contact",
                        p.step,
                        p.load_factor,
                        p.err,
                        p.max_displacement,
                        p.contact.nodes_in_contact
                    ));
                }
            };
            let mut solved = s.apply(updates, &mut observe).map_err(|e| e.to_string())?;
            let sigma =
                self.uncertainty.and_then(|samples| sigma(&mut s, &mut solved, samples, &log));
            let threads = rayon::current_num_threads();
            let ctx = RunContext { total_seconds: started.elapsed().as_secs_f64(), threads };
            let report = report(s.run(), &solved, ctx);
            let p = &s.run().prepared;
            let u = solved.solution.displacements;
            let surface = bs_scene::output::deformed_boundary(&p.mesh, &u);
            let result = RunResult::new(&p.path, p.mesh.clone(), u, p.scene.space, p.scene.units)
                .map_err(|e| e.to_string())?;
            let mut result = result.with_skull(p.skull.clone());
            result.resected = p.resection.is_some();
            let solve_seconds = started.elapsed().as_secs_f64();
            Ok(Solution { result, report, surface, solve_seconds, sigma })
        })
    }

    /// The inverse map of `result` on the image's grid, and the image's pre-operative gap
    /// (computed once per reference configuration).
    pub fn map(&self, result: &RunResult) -> Result<(InverseMap, Gap), String> {
        self.pool.install(|| {
            let map = InverseMap::new(result, &self.image.grid, &self.image_path)
                .map_err(|e| e.to_string())?;
            if map.gap_voxels().is_empty() {
                return Ok((map, Arc::new(None)));
            }
            let key = map.preop_key();
            let mut cache = self.gap.lock().unwrap_or_else(|e| e.into_inner());
            let gap = match &*cache {
                Some((k, gap)) if *k == key => gap.clone(),
                _ => {
                    let gap = Arc::new(map.preop_gap(&self.image.grid));
                    *cache = Some((key, gap.clone()));
                    gap
                }
            };
            Ok((map, gap))
        })
    }

    /// Runs `f` on the server's solver threads.
    pub fn install<T: Send>(&self, f: impl FnOnce() -> T + Send) -> T {
        self.pool.install(f)
    }
}

/// σ of the session's answer `solved` from `samples` samples, per node in mm, kept in
/// `solved` for the report; a sampling that fails is logged and leaves the answer without
/// one (the update itself stands).
fn sigma(
    s: &mut Session,
    solved: &mut bs_scene::Solved,
    samples: usize,
    log: &Log,
) -> Option<Vec<f64>> {
    let params = bs_scene::uncertainty::UncertaintyParams { samples, ..Default::default() };
    match s.uncertainty(solved, &params) {
        Ok(u) => {
            let mm = s.run().prepared.scene.units.metres() / 1e-3;
            let sigma = (0..u.sigma.len()).map(|a| u.total(a) * mm).collect();
            solved.uncertainty = Some(u);
            Some(sigma)
        }
        Err(e) => {
            log.line(&format!("  uncertainty not sampled: {e}"));
            None
        }
    }
}

/// The node set measurements move: `--set`, else the scene's only prescribed one (none for
/// a scene whose intra-operative data are all measurements).
fn choose_set(s: &Session, o: &Options) -> Result<Option<String>, String> {
    let sets = s.prescribed_sets();
    let scene = o.scene.display();
    let list = if sets.is_empty() { "none".to_string() } else { sets.join(", ") };
    match &o.set {
        Some(name) if sets.contains(&name.as_str()) => Ok(Some(name.clone())),
        Some(name) => Err(format!(
            "{scene}: --set {name}: not a prescribed node set of the scene (prescribed: {list})"
        )),
        None if sets.len() == 1 => Ok(Some(sets[0].to_string())),
        None if sets.is_empty() && !s.measured_sets().is_empty() => Ok(None),
        None => Err(format!(
            "{scene}: the scene prescribes {} node sets ({list}); name the one measurements \
             move with --set",
            sets.len()
        )),
    }
}
