//! `brainshift warp --image PREOP --result RUNDIR --out WARPED`: the pre-operative image
//! resampled into the intra-operative configuration of a run's result
//! ([`bs_scene::registration::warp_file`]).

use std::path::Path;
use std::process::ExitCode;

use bs_scene::SceneError;
use bs_scene::outside::{Boundary, OutsideReport};
use bs_scene::registration::Summary;

/// Runs `warp` and prints what it did.
pub fn run(image: &Path, result: &Path, out: &Path, labels: bool) -> Result<ExitCode, SceneError> {
    let summary = bs_scene::registration::warp_file(result, image, out, labels)?;
    print_summary("warped", &summary, if labels { "nearest label" } else { "trilinear" });
    Ok(ExitCode::SUCCESS)
}

/// The lines `warp` and `field` print.
pub(crate) fn print_summary(what: &str, s: &Summary, how: &str) {
    for n in &s.notes {
        eprintln!("note: {n}");
    }
    crate::emit(&format!(
        "{what} {} of {} voxels inside the deformed brain ({how}; max displacement {:.3} mm): \
         read {:.3} s, map {:.3} s, write {:.3} s\nwrote {}\n",
        s.inside,
        s.voxels,
        s.max_displacement,
        s.read_seconds,
        s.map_seconds,
        s.write_seconds,
        s.out.display()
    ));
    if let Some(o) = &s.outside {
        crate::emit(&format!("{}\n", outside_line(o)));
    }
}

/// The line about the map between the deformed brain and the skull.
pub(crate) fn outside_line(o: &OutsideReport) -> String {
    let to = match o.boundary {
        Boundary::Skull => "zero at the skull".to_string(),
        Boundary::Band(w) => format!("no skull: zero {w:.1} mm from the deformed brain"),
    };
    let f = &o.folding;
    format!(
        "outside the brain: {} gap voxels extended harmonically ({to}; {} iterations, \
         residual {:.1e}); det(I + grad d) min {:.3}, {} voxels <= 0{}",
        o.gap_voxels,
        o.iterations,
        o.residual,
        f.min,
        f.non_positive,
        if f.non_positive > 0 {
            " (the map folds there: the brain moved farther than the gap it left allows)"
        } else {
            " (invertible)"
        }
    )
}
