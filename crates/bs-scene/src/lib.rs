//! Brain-shift scenes as a library, between the solver crates and every front end (the
//! `brainshift` binary, the Python bindings, the OpenIGTLink server, bs-study's studies and
//! benchmarks, the fuzzer).
//!
//! The data flow, one module per step:
//!
//! * [`scene`]: the scene file (TOML) and its keys — the contract users write;
//! * [`prepare`] (with `boundary` and `loads`, displacements from an intra-operative
//!   surface or landmark pairs): files read, sets resolved, everything checked that
//!   can be checked without computing — a [`Prepared`] scene;
//! * [`compose`] (with `skull_contact`): model, loads and contact handler, the only
//!   place that knows both bs-dr and bs-contact;
//! * `gap`: exact brain–skull gaps, the initial check;
//! * [`solve`]: the solver a scene asks for, prepared once and driven with an observer;
//! * [`verify`]: the result checked independently of the solver (contact, J, equilibrium);
//! * [`Run`] and [`output`]: the verified run of a scene and its result files;
//! * [`Session`]: the live loop (boundary values, scans, landmarks, gravity, a resection,
//!   each solved warm from the last good state);
//! * (a run's result applied to images — the warp, the field, the preview's planes — is
//!   bs-register's, above this crate);
//! * [`uncertainty`]: σ of a fitted answer, sampled through the converged tangent after
//!   its solve (`run --uncertainty`) and scaled by held-out landmarks;
//! * [`check`]: everything `run` does before solving, with [`memory`] and `advice`;
//! * [`speed_accuracy`]: the speed-against-accuracy findings `check` advises from (the study
//!   that measures them is bs-study's).
//!
//! Public modules are those another crate names; the rest (`advice`, `boundary`, `gap`,
//! `gravity`, `imposed`, `landmark_fit`, `loads`, `resection`, `run`, `session`,
//! `skull_contact`) are reached through the re-exports below or not at all.
//!
//! [`mesh_scene`] makes a scene folder from a labelmap (`brainshift mesh`, via bs-meshgen).
//!
//! (Parameter sweeps — a folder of planned scenes, runs any runner fills idempotently, and
//! one table — are bs-sweep's, above this crate.)
//!
//! Every error is a [`SceneError`] naming the file and the key, set, node or element.
//!
//! Files:
//! * `scene/`: the TOML contract, one file per table: `mod.rs` (`Scene` and the schema
//!   example), `file.rs` (`[mesh]`, `[output]`, reading and the checks), `frame.rs` (`units`,
//!   `space`), `material.rs` (`[mesh] element`, `[[region]]`), `boundary.rs`
//!   (`[[boundary]]`), `gravity.rs` (`[gravity]`), `measurement.rs` (`[[measurement]]`),
//!   `solver.rs` (`[contact]`, `[solver]`), `uncertainty.rs` (`[uncertainty]`);
//! * `prepare.rs`: `Prepared` (`load`, `from_scene`, `from_parts`, `require_supported`);
//! * `boundary.rs`: `[[boundary]]` resolved to per-node prescribed components;
//! * `loads.rs`: displacements from an intra-operative surface or landmark pairs;
//! * `measure/`: `[[measurement]]` read and checked at preparation (`read.rs`, landmark
//!   files in `pairs.rs`), made into bs-fit's terms at composition (`terms.rs`), reported
//!   after the solve (`outcome.rs`), a pull that cannot be carried explained (`failure.rs`)
//!   and answered by the prior (`fallback.rs`), and which fit a scene asks for, for runs
//!   and sessions alike (`dispatch.rs`);
//! * `imposed.rs`: an element inverted by imposed data alone, named as such;
//! * `landmark_fit.rs`: landmarks fitted through the boundary the shift comes from (bs-fit's
//!   `boundary_fit` composed with the scene's model; with `[gravity] estimate`, jointly
//!   with gravity's unknowns);
//! * `estimate/`: `[gravity] estimate`'s unknowns from a scan: `mod.rs` (probes, Broyden,
//!   line search), `params.rs` (the unknowns), `residuals.rs`, `gauss_newton.rs`;
//! * `uncertainty/`: `mod.rs` (the sampling), `draws.rs` (one sample's change),
//!   `sigma.rs` (σ per node and landmark), `held_out.rs` (held-out landmarks),
//!   `truncation.rs` (the scale for the solves' loose stop);
//! * `resection.rs`: resected regions removed, cavity walls found, orphan nodes held;
//! * `gravity.rs`: `[gravity]` as bs-dr's `BodyForce` in the model's units;
//! * `compose.rs`: `Composed`, `compose`, `compose_with`: the model, loads and contact;
//! * `skull_contact.rs`: `SkullContact`, bs-contact's handlers behind bs-dr's `Contact`;
//! * `gap.rs`: `exact_gaps`;
//! * `solve.rs`: `SolveSettings`, `prepare_solver`, `solve_composed`, `solve_composed_from`;
//! * `verify.rs`: `verify`, `equilibrium_bound`, `contact_state`;
//! * `run.rs`: `Run` (`prepare`, `solve`) and `Solved`;
//! * `output.rs`: `RunReport` (report.json, read back by `RunReport::read`), `report`,
//!   `write_outputs`, `deformed_boundary`;
//! * `session/`: the live loop `Session`: `mod.rs`, `update.rs` (`Update`, `BoundaryValues`),
//!   `apply.rs` (`Session::apply`), `sets.rs` and `boundaries.rs` (prescribed boundaries
//!   resolved once, new values written in), `history.rs` (the secant predictor's states),
//!   `points.rs` (new scans), `landmarks.rs` (new landmark pairs), `gravity.rs` (gravity
//!   turned), `resect.rs` (a resection), `uncertainty.rs` (σ after an update);
//! * `check.rs`: `check`, `Checked`, `CheckReport`;
//! * `memory.rs`: the peak estimate and its refusal; `advice.rs`: `advise`;
//!   `region_effect.rs`: `region_effects` (`check --region-effect`);
//! * `speed_accuracy.rs`: `Findings` (the embedded `data/speed-accuracy.json`);
//! * `mesh_scene.rs`: `mesh_to_scene`, `write_scene_folder` (`brainshift mesh`);
//! * `error.rs`: `SceneError` and `VerifyError`.
//!
//! Architecture invariant: no numerics of its own (no element kernels, no closest-point
//! geometry) and no user interface: it prints nothing, parses no command line and shows no
//! progress (front ends pass an observer).
//!
//! ```no_run
//! use bs_scene::{Prepared, Run};
//!
//! let prepared = Prepared::load("fixtures/mni152/scene.toml".as_ref())?;
//! let mut run = Run::prepare(prepared)?;
//! let solved = run.solve(&mut |_progress| {})?;
//! println!("max |u| = {}", solved.solution.displacements.iter().map(|d| d.norm()).fold(0.0, f64::max));
//! # Ok::<(), bs_scene::SceneError>(())
//! ```

mod advice;
mod boundary;
pub mod check;
pub mod compose;
mod error;
pub mod estimate;
mod gap;
mod gravity;
mod imposed;
mod landmark_fit;
mod loads;
pub mod measure;
pub mod memory;
pub mod mesh_scene;
pub mod output;
pub mod prepare;
pub mod region_effect;
mod resection;
mod run;
pub mod scene;
mod session;
mod skull_contact;
pub mod solve;
pub mod speed_accuracy;
pub mod uncertainty;
pub mod verify;

pub use bs_dr::Progress;
pub use error::SceneError;
pub use prepare::Prepared;
pub use run::{Run, Solved};
pub use scene::Scene;
pub use session::{BoundaryValues, Session, Update};
