//! `brainshift serve`: the native OpenIGTLink server of bs-serve, in this binary (nothing
//! else to install), logging to standard output.

use std::process::ExitCode;

/// Serves until Ctrl-C; an error before listening (scene, image, `--set`, address) is
/// returned for `main` to print.
pub fn run(o: &bs_serve::Options) -> Result<ExitCode, Box<dyn std::error::Error>> {
    bs_serve::run(o, bs_serve::Log::stdout())?;
    Ok(ExitCode::SUCCESS)
}
