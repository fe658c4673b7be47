//! `run --uncertainty N`: σ of the fitted answer sampled after the solve
//! (`bs_scene::uncertainty`), as report.json's section and uncertainty.csv (bs-scene) and as
//! a float32 volume of the intra-operative configuration (bs-register), made before anything
//! is written.

use bs_register::registration::{NodalImage, RunResult};
use bs_scene::uncertainty::{UncertaintyParams, UncertaintyReport};
use bs_scene::{Run, SceneError, Solved};

use std::path::Path;

/// The σ volume's file in a result folder.
pub const UNCERTAINTY_NII: &str = "uncertainty.nii.gz";

/// Samples σ of `solved` into it and returns its volume (total σ in mm) on the grid of
/// `grid` (an image; `None`: around the deformed brain), for the result folder `out`.
pub fn sample(
    run: &mut Run,
    solved: &mut Solved,
    (samples, rtol): (usize, Option<f64>),
    (out, grid, quiet): (&Path, Option<&Path>, bool),
) -> Result<NodalImage, SceneError> {
    if !quiet {
        eprintln!(
            "uncertainty: {samples} samples of the data's noise through the converged tangent…"
        );
    }
    let defaults = UncertaintyParams::default();
    let params = UncertaintyParams { samples, rtol: rtol.unwrap_or(defaults.rtol), ..defaults };
    let u = bs_scene::uncertainty::sample(run, solved, &params)?;
    let p = &run.prepared;
    let mm = p.scene.units.metres() / 1e-3;
    let totals: Vec<f64> = (0..u.sigma.len()).map(|a| u.total(a) * mm).collect();
    let result = RunResult::new(
        out,
        p.mesh.clone(),
        solved.solution.displacements.clone(),
        p.scene.space,
        p.scene.units,
    )?;
    let image = NodalImage::new(&result, &totals, grid)?;
    solved.uncertainty = Some(u);
    Ok(image)
}

/// The run line of the uncertainty (`u` the scene's length unit).
pub fn line(r: &UncertaintyReport, u: &str) -> String {
    let [x, y, z] = r.max_at;
    let model = match &r.held_out {
        None => "the model's own error is not in it".to_string(),
        Some(h) => format!(
            "{} held-out landmarks miss by {:.3} {u} rms against {:.3} {u} predicted, \
             σ scaled × {:.2}",
            h.landmarks, h.rms_miss, h.rms_predicted, h.scale
        ),
    };
    format!(
        "uncertainty from {} samples ({}) in {:.2} s, {} GMRES iterations to {:.0e} (σ × {:.3} \
         for that stop): σ up to {:.3} {u} at node {} ({x:.1}, {y:.1}, {z:.1}), mean {:.3} \
         {u}; {model}",
        r.samples,
        r.parts.join(", "),
        r.seconds,
        r.iterations,
        r.tolerance,
        r.tolerance_scale,
        r.max_sigma,
        r.max_node,
        r.mean_sigma
    )
}
