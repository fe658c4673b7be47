//! Integration tests of the TLED kernels and the solvers (one test binary to keep link
//! times down).
#![allow(clippy::needless_range_loop)]

mod common;
mod contact_seam;
mod gravity;
mod guard;
mod homogeneous;
mod locking;
mod newton_krylov;
mod newton_vs_dr;
mod parallel;
