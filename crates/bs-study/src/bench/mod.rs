//! The benchmarks `cargo xtask bench …` runs (xtask parses their arguments): each prints
//! its measurements as ratios against a baseline run in the same process (these machines are
//! shared and noisy) and, for its default run, writes its block of `docs/benchmarks.md`
//! (`page.rs`).
//!
//! * `solver.rs`: the TLED kernels' ns per element-step (1 and 2 threads), the preconditioners'
//!   cycles against the memory bandwidth, DR against Newton–Krylov;
//! * `contact.rs`: the paper's contact benchmark for every handler (`docs/contact-bench.md`);
//! * `e2e.rs`: every contact fixture solved by DR and by Newton–Krylov in child processes,
//!   against CalculiX, then the 852k-tet mesh and the loads other than the push;
//! * `mesh.rs`: `brainshift mesh` at 4 mm on the MNI152 mask and an ellipsoid labelmap;
//! * `warp.rs`: the registration outputs on the MNI152 T1 grid against reading the image;
//! * `update.rs`: a live session's warm updates against cold solves of the same loads;
//! * `fit.rs`: fitting a scan against imposing what it measures, the gravity estimate and the
//!   uncertainty's samples;
//! * `serve.rs`: `brainshift serve` over OpenIGTLink on loopback, last byte sent to the
//!   warped image received.

pub mod contact;
pub mod e2e;
pub mod fit;
pub mod mesh;
mod page;
pub mod serve;
pub mod solver;
pub mod update;
pub mod warp;
