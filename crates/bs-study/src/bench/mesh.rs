//! `cargo xtask bench mesh`: wall time of `brainshift mesh`'s meshing (labelmap in memory →
//! brain mesh, skull cavity, checks) at 4 mm on the MNI152 brain mask
//! (`fixtures/mni152/mask.nii.gz`, 197×233×189 voxels of 1 mm, 1.88 M brain voxels) and on
//! a synthetic ellipsoid labelmap of the same size, in rayon pools of 1 and 2 threads:
//! best and median of 5 runs after a warm-up, with the steps of the best run.

use std::path::Path;
use std::time::Instant;

use bs_image::{Grid, Volume};
use bs_meshgen::{MeshParams, mesh_labelmap};

use super::page::{Page, say};

/// The synthetic stand-in: an ellipsoid (semi-axes 72, 90, 70 mm: 1.9 M voxels) on the
/// MNI152 grid.
fn ellipsoid() -> Result<Volume<u32>, String> {
    let grid = Grid::axis_aligned([197, 233, 189], [1.0; 3], [-98.0, -134.0, -72.0])
        .map_err(|e| e.to_string())?;
    let mut v = Volume::filled(grid, 0u32);
    let (a, b, c) = (72.0, 90.0, 70.0);
    for k in 0..189 {
        for j in 0..233 {
            for i in 0..197 {
                let p = v.grid.world([i as f64, j as f64, k as f64]);
                let (x, y, z) = (p.x / a, (p.y + 18.0) / b, (p.z - 18.0) / c);
                if x * x + y * y + z * z <= 1.0 {
                    let id = v.grid.index(i, j, k);
                    v.data[id] = 1;
                }
            }
        }
    }
    Ok(v)
}

fn bench(page: &mut Page, name: &str, labels: &Volume<u32>) -> Result<(), String> {
    let params = MeshParams::default();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| e.to_string())?;
        let mut times = Vec::new();
        let mut best: Option<(f64, bs_meshgen::MeshReport)> = None;
        for run in 0..6 {
            let t = Instant::now();
            let m = pool.install(|| mesh_labelmap(labels, &params)).map_err(|e| e.to_string())?;
            let s = t.elapsed().as_secs_f64();
            if run == 0 {
                continue;
            }
            times.push(s);
            if best.as_ref().is_none_or(|b| s < b.0) {
                best = Some((s, m.report));
            }
        }
        times.sort_by(f64::total_cmp);
        let (s, r) = best.ok_or("no run")?;
        say!(
            page,
            "{name:<22} {threads} thread(s): best {s:.3} s, median {:.3} s  ({} nodes, {} tets, dihedral {:.1}..{:.1} deg, volume {:+.2}%)",
            times[times.len() / 2],
            r.nodes,
            r.elements,
            r.quality.min_dihedral_deg,
            r.quality.max_dihedral_deg,
            100.0 * r.volume_error()
        );
        let steps: Vec<String> = r.timings.iter().map(|(n, t)| format!("{n} {t:.3}")).collect();
        say!(page, "{:<22} steps of the best run: {}", "", steps.join(", "));
    }
    Ok(())
}

/// Runs the benchmark.
pub fn run() -> Result<(), String> {
    let mut page = Page::new("mesh");
    let mask = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/mni152/mask.nii.gz");
    if mask.is_file() {
        let t = Instant::now();
        let labels = bs_image::nifti::read_labels(&mask).map_err(|e| e.to_string())?;
        say!(page, "read fixtures/mni152/mask.nii.gz in {:.3} s", t.elapsed().as_secs_f64());
        bench(&mut page, "MNI152 mask, 4 mm", &labels)?;
    } else {
        say!(page, "{} not found: synthetic labelmap only", mask.display());
    }
    bench(&mut page, "ellipsoid 197x233x189", &ellipsoid()?)?;
    page.write("cargo xtask bench mesh")
}
