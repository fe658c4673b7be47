//! `brainshift field --reference IMAGE --result RUNDIR --out FIELD`: a run's result as a
//! displacement field on an image's grid, for ITK and 3D Slicer
//! ([`bs_register::registration::field_file`]).

use std::path::Path;
use std::process::ExitCode;

use bs_scene::SceneError;

/// Runs `field` and prints what it did.
pub fn run(reference: &Path, result: &Path, out: &Path) -> Result<ExitCode, SceneError> {
    let summary = bs_register::registration::field_file(result, reference, out)?;
    crate::warp::print_summary("mapped", &summary, "d(y) = X(y) - y, zero beyond the skull");
    Ok(ExitCode::SUCCESS)
}
