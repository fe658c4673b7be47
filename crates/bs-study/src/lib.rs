//! brainshift's evidence, as a library `cargo xtask` drives and `cargo test` checks: every
//! number the docs quote about accuracy, stability and speed against accuracy is made here.
//!
//! * [`study`]: one scene solved with variations (element, tolerance, handler, solver), an
//!   [`study::Outcome`] per run; [`verdict`]: how such a run ended (converged, stopped by a
//!   guard, failed silently);
//! * [`calculix`]: a scene written as a CalculiX deck and the reference solution read back;
//!   [`reference`]: runs `ccx` on the fixtures and stores the references;
//! * [`validate`]: every reference case in one table (closed forms, DR against
//!   Newton–Krylov, contact against brute force, DR + contact against CalculiX);
//! * [`stability`]: the stability map (time step, Poisson's ratio, hourglass control, load
//!   until inversion, contact at sharp corners), its knife-edge and trace tools;
//! * [`chart`] (drawn with [`plot`]): speed against accuracy, its points, Pareto front and
//!   the findings `brainshift check` embeds in [`speed_accuracy`];
//! * [`fit`]: the measurement-fit fixture and study; [`ghost`]: the warped image where the
//!   brain moved away;
//! * [`bench`]: the benchmarks (`cargo xtask bench …`), ratios against a baseline run in the
//!   same process;
//! * [`util`]: where the repository is, atomic page blocks between markers.
//!
//! Nothing here is part of the product: bs-scene and the front ends never depend on it.

pub mod bench;
pub mod calculix;
pub mod chart;
pub mod fit;
pub mod ghost;
pub mod plot;
pub mod precond;
pub mod reference;
pub mod speed_accuracy;
pub mod stability;
pub mod study;
pub mod util;
pub mod validate;
pub mod verdict;
