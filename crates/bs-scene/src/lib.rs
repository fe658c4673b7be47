//! Brain-shift scenes as a library, between the solver crates and every front end (the
//! `brainshift` binary, the Python bindings, `cargo xtask`).
//!
//! The data flow, one module per step:
//!
//! * [`scene`]: the scene file (TOML) and its keys — the contract users write;
//! * [`prepare`] (with [`boundary`] and `loads`, displacements from an intra-operative
//!   surface or landmark pairs): files read, sets resolved, everything checked that
//!   can be checked without computing — a [`Prepared`] scene;
//! * [`compose`] (with [`skull_contact`]): model, loads and contact handler, the only
//!   place that knows both bs-dr and bs-contact;
//! * [`gap`]: exact brain–skull gaps, the initial check;
//! * [`solve`]: the solver a scene asks for, prepared once and driven with an observer;
//! * [`verify`]: the result checked independently of the solver (contact, J, equilibrium);
//! * [`run`] and [`output`]: the verified run of a scene and its three files;
//! * (a run's result applied to images — the warp, the field, the preview's planes — is
//!   bs-register's, above this crate);
//! * [`uncertainty`]: σ of a fitted answer, sampled through the converged tangent after
//!   its solve (`run --uncertainty`) and scaled by held-out landmarks;
//! * [`check`]: everything `run` does before solving, with [`memory`] and [`advice`];
//! * [`findings`]: the speed-versus-accuracy results `check` advises from, typed end to end
//!   (the studies that measure them are bs-study's, driven by `cargo xtask`).
//!
//! [`mesh_scene`] makes a scene folder from a labelmap (`brainshift mesh`, via bs-meshgen).
//!
//! (Parameter sweeps — a folder of planned scenes, runs any runner fills idempotently, and
//! one table — are bs-sweep's, above this crate.)
//!
//! Every error is a [`SceneError`] naming the file and the key, set, node or element.
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

pub mod advice;
pub mod boundary;
pub mod check;
pub mod compose;
mod error;
pub mod estimate;
pub mod findings;
pub mod gap;
pub mod gravity;
mod imposed;
pub mod inverse;
mod loads;
pub mod measure;
pub mod memory;
pub mod mesh_scene;
pub mod output;
pub mod prepare;
pub mod region_effect;
pub mod resection;
pub mod run;
pub mod scene;
pub mod session;
pub mod skull_contact;
pub mod solve;
pub mod uncertainty;
pub mod verify;

pub use bs_dr::Progress;
pub use error::SceneError;
pub use prepare::Prepared;
pub use run::{Run, Solved};
pub use scene::Scene;
pub use session::{BoundaryValues, Session, Update};
