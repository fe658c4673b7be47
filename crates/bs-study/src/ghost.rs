//! `cargo xtask ghost`: how much of the old brain the warped image still shows where the
//! brain moved away (the "ghost"), and how well the exported field reproduces the nodes'
//! motion, on the demo case (the MNI152 scene solved in process, its T1 template and brain
//! mask), for the map outside the brain as it was (the identity) and as it is (the
//! harmonic extension to the skull).
//!
//! * Ghost: the voxels inside the pre-operative brain mask (`fixtures/mni152/mask.nii.gz`),
//!   outside the deformed brain, whose nearest deformed brain-surface node moved more than
//!   4 mm (the space the brain left near the craniotomy); the mean of the warped T1 there,
//!   relative to the T1's mean over the whole mask. Cortex left in place reads about 1, fluid
//!   (what is there after the shift) much less.
//! * Field: at the 50 most displaced nodes, the field trilinearly interpolated (as ITK does)
//!   at the deformed position X + u, against −u.

use std::path::Path;

use bs_image::Volume;
use bs_mesh::{Point3, Vector3};
use bs_register::registration::{InverseMap, OutsideChoice, RunResult};
use bs_scene::{Prepared, Run};
use rayon::prelude::*;

/// Surface that moved more than this (mm) defines the vacated region.
const MOVED_MM: f64 = 4.0;
/// Nodes at which the field is checked.
const NODES: usize = 50;

/// Runs the measurement and prints the table.
pub fn main() -> Result<(), String> {
    let root = crate::util::root();
    let fx = root.join("fixtures/mni152");
    let prepared = Prepared::load(&fx.join("scene.toml")).map_err(|e| e.to_string())?;
    let (mesh, skull) = (prepared.mesh.clone(), prepared.skull.clone());
    let (space, units) = (prepared.scene.space, prepared.scene.units);
    let mut run = Run::prepare(prepared).map_err(|e| e.to_string())?;
    let solved = run.solve(&mut |_| {}).map_err(|e| e.to_string())?;
    let u = solved.solution.displacements.clone();
    let result = RunResult::new(Path::new("(demo)"), mesh.clone(), u.clone(), space, units)
        .map_err(|e| e.to_string())?
        .with_skull(skull);
    let t1 = bs_image::nifti::read_image(&fx.join("t1.nii.gz")).map_err(|e| e.to_string())?;
    let mask = bs_image::nifti::read_labels(&fx.join("mask.nii.gz")).map_err(|e| e.to_string())?;
    let g = &t1.volume.grid;
    if mask.grid != *g {
        return Err("mask.nii.gz and t1.nii.gz are not on the same grid".into());
    }
    let in_mask: Vec<bool> = mask.data.iter().map(|&l| l != 0).collect();
    let brain_mean = mean(&t1.volume.data, &in_mask);

    // The deformed boundary nodes and how far each moved (the mesh is RAS mm, as the image).
    let boundary = mesh.boundary();
    let surface: Vec<(Point3<f64>, f64)> =
        boundary.volume_node.iter().map(|&n| (mesh.nodes[n] + u[n], u[n].norm())).collect();

    println!(
        "ghost: MNI152 demo (max |u| {:.2} mm), T1 {:?}, brain mean {brain_mean:.1}",
        result.max_displacement_mm(),
        g.dims()
    );
    println!(
        "| map outside the brain | vacated voxels | ghost (mean / brain mean) | field(X+u) vs -u at {NODES} nodes: max, mean (mm) | det(I + grad d): min, voxels <= 0 |"
    );
    println!("|---|---|---|---|---|");
    for (name, choice) in [
        ("identity (before)", OutsideChoice::Identity),
        ("harmonic extension to the skull", OutsideChoice::Extend),
    ] {
        let map = InverseMap::with_outside(&result, g, &fx.join("t1.nii.gz"), choice)
            .map_err(|e| e.to_string())?;
        let warped = map.warp(&t1.volume, &t1.volume.data);
        let vacated = vacated(&map, &in_mask, &surface, g);
        let count = vacated.iter().filter(|&&v| v).count();
        let ghost = mean(&warped, &vacated) / brain_mean;
        let (max_e, mean_e) = field_error(&map, &mesh.nodes, &u);
        let folding = map
            .outside_report()
            .map(|o| format!("{:.3}, {}", o.folding.min, o.folding.non_positive))
            .unwrap_or_else(|| "-".into());
        println!("| {name} | {count} | {ghost:.3} | {max_e:.3}, {mean_e:.3} | {folding} |");
    }
    println!("(command: cargo xtask ghost)");
    Ok(())
}

fn mean(values: &[f32], mask: &[bool]) -> f64 {
    let (s, n) = values
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .fold((0.0f64, 0usize), |(s, n), (&v, _)| (s + v as f64, n + 1));
    s / n.max(1) as f64
}

/// Voxels in the pre-operative mask, outside the deformed brain, whose nearest deformed
/// surface node moved more than [`MOVED_MM`].
fn vacated(
    map: &InverseMap,
    in_mask: &[bool],
    surface: &[(Point3<f64>, f64)],
    g: &bs_image::Grid,
) -> Vec<bool> {
    let [nx, ny, _] = g.dims();
    (0..g.len())
        .into_par_iter()
        .map(|n| {
            if !in_mask[n] || map.reference_point(n).is_some() {
                return false;
            }
            let y = g.world([(n % nx) as f64, ((n / nx) % ny) as f64, (n / (nx * ny)) as f64]);
            let nearest = surface
                .iter()
                .map(|(p, moved)| ((p - y).norm_squared(), *moved))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            nearest.is_some_and(|(_, moved)| moved > MOVED_MM)
        })
        .collect()
}

/// Max and mean of |field(X + u) + u| over the [`NODES`] most displaced nodes, the field
/// interpolated trilinearly from its float32 voxels.
fn field_error(map: &InverseMap, nodes: &[Point3<f64>], u: &[Vector3<f64>]) -> (f64, f64) {
    let g = map.grid();
    let field = map.field();
    let comps: Vec<Volume<f32>> = (0..3)
        .map(|c| Volume { grid: g.clone(), data: field.iter().map(|d| d[c]).collect() })
        .collect();
    let mut order: Vec<usize> = (0..nodes.len()).collect();
    order.sort_by(|&a, &b| u[b].norm().total_cmp(&u[a].norm()));
    let errors: Vec<f64> = order[..NODES.min(order.len())]
        .iter()
        .filter_map(|&n| {
            let x = nodes[n] + u[n];
            let d = Vector3::from_fn(|c, _| {
                bs_image::sample::trilinear(&comps[c], &x).map_or(f64::NAN, |v| v as f64)
            });
            let e = (d + u[n]).norm();
            e.is_finite().then_some(e)
        })
        .collect();
    let max = errors.iter().copied().fold(0.0, f64::max);
    (max, errors.iter().sum::<f64>() / errors.len().max(1) as f64)
}
