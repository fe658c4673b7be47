//! `brainshift warp --image PREOP --result RUNDIR --out WARPED`: the pre-operative image
//! resampled into the intra-operative configuration of a run's result
//! ([`bs_register::registration::warp_file`]).

use std::path::Path;
use std::process::ExitCode;

use bs_register::outside::{Boundary, OutsideReport};
use bs_register::registration::Summary;

/// Runs `warp` and prints what it did; with `preview`, also draws the three planes through
/// the largest displacement (or the point given with it, RAS mm) into that PNG.
pub fn run(
    image: &Path,
    result: &Path,
    out: &Path,
    labels: Option<u32>,
    (preview, at): (Option<&Path>, Option<&[f64]>),
) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let at = match at {
        None => None,
        Some(&[x, y, z]) => Some([x, y, z]),
        Some(v) => {
            let n = v.len();
            return Err(format!("--preview-at: give three numbers X,Y,Z (RAS mm), got {n}").into());
        }
    };
    if let Some(p) = preview
        && !p.to_string_lossy().to_ascii_lowercase().ends_with(".png")
    {
        return Err(format!(
            "--preview {}: the preview is a PNG picture; name it .png",
            p.display()
        )
        .into());
    }
    let summary =
        bs_register::registration::warp_file(result, image, out, labels, preview.map(|_| at))?;
    let sampling = if labels.is_some() { "nearest label" } else { "trilinear" };
    print_summary("warped", &summary, sampling);
    if let (Some(path), Some(planes)) = (preview, &summary.planes) {
        draw_preview(path, image, planes)?;
        crate::emit(&format!("wrote {} (preview)\n", path.display()));
    }
    Ok(ExitCode::SUCCESS)
}

/// The preview picture: pre-operative, warped and |d| on three planes.
fn draw_preview(
    path: &Path,
    image: &Path,
    p: &bs_register::planes::Planes,
) -> Result<(), bs_preview::PreviewError> {
    let name = image.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let title = format!(
        "{name}: brain shift, largest displacement {:.1} mm; slices through voxel ({}, {}, {})",
        p.max_mm, p.voxel[0], p.voxel[1], p.voxel[2]
    );
    bs_preview::render(path, &title, &p.planes, p.window, p.max_mm)
}

/// The lines `warp` and `field` print.
pub(crate) fn print_summary(what: &str, s: &Summary, how: &str) {
    for n in &s.notes {
        eprintln!("note: {n}");
    }
    let gap = s.gap_max_displacement.map_or(String::new(), |g| format!(", {g:.3} mm in the gap"));
    crate::emit(&format!(
        "{what} {} of {} voxels inside the deformed brain ({how}; max displacement {:.3} mm{gap}): \
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
    let at = o
        .worst_at
        .map(|p| format!(" at ({:.1}, {:.1}, {:.1}) mm", p[0], p[1], p[2]))
        .unwrap_or_default();
    format!(
        "outside the brain: {} gap voxels extended harmonically ({to}; {} iterations, \
         residual {:.1e}); det(I + grad d) min {:.3}{at}, {} voxels <= 0{}",
        o.gap_voxels,
        o.iterations,
        o.residual,
        f.min,
        f.non_positive,
        if f.non_positive > 0 {
            " (the map y -> y + d(y) folds there: a gap narrower than the voxels or than the shift)"
        } else {
            " (invertible)"
        }
    )
}
