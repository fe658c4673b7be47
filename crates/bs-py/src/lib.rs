//! `brainshift._native`: the Python bindings of brainshift (re-exported by the pure-Python
//! package `brainshift`, python/brainshift). Every entry point calls the same bs-scene
//! functions as the `brainshift` command, so a scene run from Python writes bit-identical
//! displacements; errors carry the command's messages.
//!
//! The GIL is released while files are read and scenes solved (`Python::detach`); a progress
//! callback re-attaches for each call.
//!
//! Files (one per class or job; `lib.rs` registers them and `BrainshiftError`):
//! * `scene.rs`: `Scene` from a file or from arrays; `check` and `run`;
//! * `result.rs`: `Result`: displacements, report, outputs, `warp`, `field`,
//!   `inverse_map`, `surface`;
//! * `session.rs`: `Session` over `bs_scene::Session`: `update`, `reset`;
//! * `image.rs`: `Image`, a pre-operative image read once and kept in memory, and the
//!   `InverseMap` a `Result` reuses for warp and field;
//! * `functions.rs`: `read_mesh` and `gap`;
//! * `sweeps.rs`: the sweep functions of bs-sweep (plan, run, collect, emit Slurm);
//! * `igtl.rs`: `crc64`, bs-igtl's checksum for Python clients;
//! * `serve.rs`: `serve(argv)`, bs-serve's server with bs-serve's option declaration;
//! * `convert.rs`: errors as exceptions, arrays as brainshift types, thread pools,
//!   progress callbacks.
//!
//! Architecture invariant: a front end like bs-cli: it knows the scene and the session,
//! never the solver or the composition.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

mod convert;
mod functions;
mod igtl;
mod image;
mod result;
mod scene;
mod serve;
mod session;
mod sweeps;

create_exception!(
    brainshift,
    BrainshiftError,
    PyException,
    "A scene, mesh, sweep or run that brainshift refuses, with the command line's message \
     (naming the file and key); `kind` is a short stable name of the error kind."
);

/// The native module `brainshift._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("BrainshiftError", m.py().get_type::<BrainshiftError>())?;
    m.add_class::<scene::Scene>()?;
    m.add_class::<result::VerifiedRun>()?;
    m.add_class::<session::Session>()?;
    m.add_class::<image::Image>()?;
    m.add_class::<image::InverseMap>()?;
    m.add_function(wrap_pyfunction!(image::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(igtl::crc64, m)?)?;
    m.add_function(wrap_pyfunction!(serve::serve, m)?)?;
    m.add_function(wrap_pyfunction!(functions::read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(functions::gap, m)?)?;
    m.add_function(wrap_pyfunction!(sweeps::sweep_plan, m)?)?;
    m.add_function(wrap_pyfunction!(sweeps::sweep_run, m)?)?;
    m.add_function(wrap_pyfunction!(sweeps::sweep_collect, m)?)?;
    m.add_function(wrap_pyfunction!(sweeps::sweep_emit_slurm, m)?)?;
    Ok(())
}
