//! `cargo xtask bench warp`: the registration outputs on the demo case. Solves the MNI152
//! scene once (not timed), then times, on the T1 template's full grid (197 × 233 × 189):
//! reading the image (the baseline every warp pays), the inverse map (lattice location of
//! every voxel in the deformed mesh, then the harmonic extension to the skull: its
//! rasterised cavity and the gap solve; the exact map alone timed too) with the trilinear
//! resampling, and the displacement field; and, for the ratio, the naive per-voxel `TetLocator::locate` on the deformed mesh
//! over a 1-in-64 subsample of the voxels in the mesh's bounding box, scaled to all of them.
//! Best of 3 runs each; the table is printed and written into docs/benchmarks.md.

use std::path::Path;
use std::time::Instant;

use bs_mesh::{Mesh, Point3};
use bs_register::registration::{InverseMap, OutsideChoice, RunResult};
use bs_scene::{Prepared, Run};

use super::page::{Page, say};

fn best<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut out = None;
    let mut best = f64::INFINITY;
    for _ in 0..runs {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("at least one run"))
}

/// Runs the benchmark.
pub fn run() -> Result<(), String> {
    let root = crate::util::root();
    let scene = root.join("fixtures/mni152/scene.toml");
    let t1 = root.join("fixtures/mni152/t1.nii.gz");
    let prepared = Prepared::load(&scene).map_err(|e| e.to_string())?;
    let mesh: Mesh = prepared.mesh.clone();
    let skull = prepared.skull.clone();
    let space = prepared.scene.space;
    let units = prepared.scene.units;
    let mut run = Run::prepare(prepared).map_err(|e| e.to_string())?;
    let solved = run.solve(&mut |_| {}).map_err(|e| e.to_string())?;
    let u = solved.solution.displacements.clone();
    let result = RunResult::new(Path::new("(demo)"), mesh.clone(), u.clone(), space, units)
        .map_err(|e| e.to_string())?
        .with_skull(skull);

    let (read, img) = best(3, || bs_image::nifti::read_image(&t1));
    let img = img.map_err(|e| e.to_string())?;
    let v = &img.volume;
    let (exact_s, _) =
        best(3, || InverseMap::with_outside(&result, &v.grid, &t1, OutsideChoice::Identity));
    let (map_s, map) = best(3, || InverseMap::new(&result, &v.grid, &t1));
    let map = map.map_err(|e| e.to_string())?;
    let outside = map.outside_report().ok_or("no extension")?;
    let (warp_s, warped) = best(3, || map.warp(v, &v.data));
    let (field_s, field) = best(3, || map.field());
    // The pre-operative gap alone, and warp and field given it (a live session's case).
    let (gap_s, gap) = best(3, || map.preop_gap(&v.grid));
    let gap = gap.ok_or("the reference mesh cannot be located on the T1 grid")?;
    let (warp_gap_s, _) = best(3, || map.warp_with_gap(v, &v.data, Some(&gap)));
    let (field_gap_s, _) = best(3, || map.field_with_gap(Some(&gap)));
    assert_eq!(warped.len(), field.len());

    // Baseline: TetLocator on the deformed mesh, one voxel at a time.
    let mut deformed = mesh.clone();
    for (p, d) in deformed.nodes.iter_mut().zip(&u) {
        *p += d;
    }
    let (lo, hi) = deformed.bounding_box().ok_or("empty mesh")?;
    let a = v.grid.voxel(&lo).map(|x| x.floor().max(0.0) as usize);
    let b = v.grid.voxel(&hi).map(|x| x.ceil().max(0.0) as usize);
    let dims = v.grid.dims();
    let range = |c: usize| (a[c]..=b[c].min(dims[c] - 1)).step_by(4);
    let (locator_build, locator) = best(1, || bs_mesh::TetLocator::new(&deformed));
    let locator = locator.map_err(|e| e.to_string())?;
    let t = Instant::now();
    let (mut sampled, mut inside) = (0usize, 0usize);
    for k in range(2) {
        for j in range(1) {
            for i in range(0) {
                let y = v.grid.world([i as f64, j as f64, k as f64]);
                let loc = locator.locate(&Point3::from(y));
                sampled += 1;
                inside += usize::from(loc.distance == 0.0);
            }
        }
    }
    let naive = t.elapsed().as_secs_f64() * 64.0 + locator_build;

    let threads = rayon::current_num_threads();
    let mut page = Page::new("warp");
    say!(
        page,
        "bench warp: MNI152 T1 {:?} = {} voxels, {} inside the deformed brain, {threads} threads",
        dims,
        v.grid.len(),
        map.inside_count()
    );
    say!(page, "| step | seconds |");
    say!(page, "|---|---|");
    say!(page, "| read t1.nii.gz (baseline) | {read:.3} |");
    say!(page, "| exact inverse map alone (lattice location) | {exact_s:.3} |");
    say!(
        page,
        "| inverse map with the extension to the skull ({} gap voxels, {} CG iterations) | {map_s:.3} |",
        outside.gap_voxels,
        outside.iterations
    );
    say!(
        page,
        "| warp (trilinear resampling; the pre-operative gap located on the grid) | {warp_s:.3} |"
    );
    say!(page, "| field d(y) = X(y) - y (the same map) | {field_s:.3} |");
    say!(page, "| the pre-operative gap alone (reference mesh located on the grid) | {gap_s:.3} |");
    say!(page, "| warp given the gap (a live session's) | {warp_gap_s:.3} |");
    say!(page, "| field given the gap | {field_gap_s:.3} |");
    say!(
        page,
        "| map + warp | {:.3} ({:.2}x the image read) |",
        map_s + warp_s,
        (map_s + warp_s) / read
    );
    say!(
        page,
        "| naive TetLocator per voxel, bbox, 1/64 sample x 64 (+ build {locator_build:.3}) | {naive:.1} ({:.0}x map + warp; {sampled} sampled, {inside} inside) |",
        naive / (map_s + warp_s)
    );
    page.write("cargo xtask bench warp")
}
