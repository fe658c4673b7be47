//! Closed-form checks of the extension and of the fold measure.

use super::*;

#[test]
fn a_slab_between_two_planes_gets_the_linear_stretch() {
    // Free voxels 1..=8 along i between fixed d = (4, 1, −2) at i = 0 and 0 at i = 9:
    // the discrete harmonic function of one variable is linear, d(i) = d₀ (9 − i) / 9,
    // whatever the voxel sizes (the j, k neighbours carry the same values).
    let grid = Grid::axis_aligned([10, 3, 4], [0.7, 1.3, 2.0], [0.0; 3]).unwrap();
    let free: Vec<bool> = (0..grid.len()).map(|n| (1..=8).contains(&(n % 10))).collect();
    let d0 = [4.0, 1.0, -2.0];
    let ext = harmonic_extension(
        &grid,
        &free,
        &|n| if n.is_multiple_of(10) { d0 } else { [0.0; 3] },
        &ExtensionParams { tolerance: 1e-10, ..ExtensionParams::default() },
    );
    assert_eq!(ext.voxels.len(), 8 * 12);
    for (&v, d) in ext.voxels.iter().zip(&ext.values) {
        let i = v as usize % 10;
        for c in 0..3 {
            let expect = d0[c] * (9 - i) as f64 / 9.0;
            assert!((d[c] - expect).abs() < 1e-6, "voxel {v}: {d:?}");
        }
    }
    // The map i ↦ x + d stretches monotonically: J = 1 + ∂d_x/∂x = 1 − 4/(9 × 0.7) > 0.
    let field = |n: usize| {
        ext.voxels
            .binary_search(&(n as u32))
            .map(|s| ext.values[s])
            .unwrap_or(if n.is_multiple_of(10) { d0 } else { [0.0; 3] })
    };
    let f = jacobian(&grid, &ext.voxels, &field);
    assert_eq!(f.non_positive, 0);
    assert!((f.min - (1.0 - 4.0 / (9.0 * 0.7))).abs() < 1e-6, "{f:?}");
}

#[test]
fn a_slab_too_large_to_solve_directly_starts_from_its_coarse_solution() {
    // The linear stretch of the first test on 38 × 40 × 40 free voxels (above the default
    // `coarsen_from`): the coarse start changes where the iteration begins, not where it
    // ends, and saves iterations (measured: 131 against 250 at this tolerance).
    let grid = Grid::axis_aligned([40, 40, 40], [1.0, 0.8, 1.2], [0.0; 3]).unwrap();
    let free: Vec<bool> = (0..grid.len()).map(|n| (1..=38).contains(&(n % 40))).collect();
    let d0 = [3.0, -1.0, 0.5];
    let fixed = |n: usize| if n.is_multiple_of(40) { d0 } else { [0.0; 3] };
    let params = ExtensionParams { tolerance: 1e-9, ..ExtensionParams::default() };
    assert!(38 * 40 * 40 >= params.coarsen_from);
    let coarse = harmonic_extension(&grid, &free, &fixed, &params);
    let direct = harmonic_extension(
        &grid,
        &free,
        &fixed,
        &ExtensionParams { coarsen_from: usize::MAX, ..params },
    );
    for ext in [&coarse, &direct] {
        for (&v, d) in ext.voxels.iter().zip(&ext.values) {
            let i = v as usize % 40;
            for c in 0..3 {
                let expect = d0[c] * (39 - i) as f64 / 39.0;
                assert!((d[c] - expect).abs() < 1e-6, "voxel {v}: {d:?} against {expect}");
            }
        }
    }
    assert!(
        4 * coarse.iterations <= 3 * direct.iterations,
        "{} against {} iterations",
        coarse.iterations,
        direct.iterations
    );
}

#[test]
fn a_gap_narrower_than_the_move_folds_and_is_reported() {
    // d₀ = 10 mm over a 9-voxel gap of 1 mm voxels: ∂d/∂x = −10/9 < −1, J < 0.
    let grid = Grid::axis_aligned([10, 1, 1], [1.0; 3], [0.0; 3]).unwrap();
    let free: Vec<bool> = (0..10).map(|i| (1..=8).contains(&i)).collect();
    let d = |n: usize| if n == 0 { [10.0, 0.0, 0.0] } else { [0.0; 3] };
    let ext = harmonic_extension(
        &grid,
        &free,
        &d,
        &ExtensionParams { tolerance: 1e-10, ..ExtensionParams::default() },
    );
    let field =
        |n: usize| ext.voxels.binary_search(&(n as u32)).map(|s| ext.values[s]).unwrap_or(d(n));
    let f = jacobian(&grid, &ext.voxels, &field);
    assert_eq!(f.non_positive, 8);
    assert!((f.min - (1.0 - 10.0 / 9.0)).abs() < 1e-6, "{f:?}");
}

#[test]
fn the_discrete_laplacian_vanishes_at_every_free_voxel_of_a_shell() {
    // A spherical shell between a ball (fixed, a rotation-like field) and the far
    // region (fixed 0) on an anisotropic grid: the residual of the weighted 7-point
    // Laplacian at every free voxel is at the solver's tolerance.
    let (grid, free, f) = shell();
    let ext = harmonic_extension(
        &grid,
        &free,
        &f,
        &ExtensionParams { tolerance: 1e-10, ..ExtensionParams::default() },
    );
    let value =
        |n: usize| ext.voxels.binary_search(&(n as u32)).map(|s| ext.values[s]).unwrap_or(f(n));
    let h = grid.spacing();
    let [nx, ny, _] = grid.dims();
    let mut worst: f64 = 0.0;
    for &v in &ext.voxels {
        let n = v as usize;
        let c = value(n);
        let mut lap = [0.0; 3];
        for (a, s) in [(0, 1), (1, nx), (2, nx * ny)] {
            for q in [n - s, n + s] {
                let vq = value(q);
                for k in 0..3 {
                    lap[k] += (vq[k] - c[k]) / (h[a] * h[a]);
                }
            }
        }
        worst = lap.iter().fold(worst, |m, x| m.max(x.abs()));
    }
    assert!(worst < 1e-5, "largest |Δd| {worst}");
}

fn idx(grid: &Grid, n: usize) -> [f64; 3] {
    let [nx, ny, _] = grid.dims();
    [(n % nx) as f64, ((n / nx) % ny) as f64, (n / (nx * ny)) as f64]
}

/// The shell of `the_discrete_laplacian_vanishes_at_every_free_voxel_of_a_shell`.
fn shell() -> (Grid, Vec<bool>, impl Fn(usize) -> [f64; 3] + Sync) {
    let grid = Grid::axis_aligned([24, 20, 16], [1.0, 1.2, 1.5], [-11.5, -11.4, -11.25]).unwrap();
    let g = grid.clone();
    let r = move |n: usize| g.world(idx(&g, n)).coords.norm();
    let free: Vec<bool> = (0..grid.len()).map(|n| (5.0..10.0).contains(&r(n))).collect();
    let g = grid.clone();
    let f = move |n: usize| {
        let p = g.world(idx(&g, n));
        if p.coords.norm() < 5.0 { [p.y, -p.x, 0.5] } else { [0.0; 3] }
    };
    (grid, free, f)
}

#[test]
fn single_precision_corrections_refine_to_a_double_precision_tolerance() {
    // The reported residual is the double-precision b − A x of the returned values,
    // recomputed here independently; 1e-11 is far below what one single-precision solve
    // reaches (its recurrence drifts from the true residual near 1e-6), so the refinement
    // rounds must have run.
    let (grid, free, f) = shell();
    let params = ExtensionParams { tolerance: 1e-11, ..ExtensionParams::default() };
    let ext = harmonic_extension(&grid, &free, &f, &params);
    assert!(ext.residual <= 1e-11, "{}", ext.residual);
    let value =
        |n: usize| ext.voxels.binary_search(&(n as u32)).map(|s| ext.values[s]).unwrap_or(f(n));
    let h = grid.spacing();
    let [nx, ny, _] = grid.dims();
    let (mut rr, mut bb) = ([0.0f64; 3], [0.0f64; 3]);
    for &v in &ext.voxels {
        let n = v as usize;
        let c = value(n);
        // Every free voxel of the shell is interior: six neighbours on the grid.
        let (mut res, mut b) = ([0.0; 3], [0.0; 3]);
        for (a, s) in [(0, 1), (1, nx), (2, nx * ny)] {
            let w = 1.0 / (h[a] * h[a]);
            for q in [n - s, n + s] {
                let vq = value(q);
                for k in 0..3 {
                    res[k] += w * (vq[k] - c[k]);
                    if !free[q] {
                        b[k] += w * vq[k];
                    }
                }
            }
        }
        for k in 0..3 {
            rr[k] += res[k] * res[k];
            bb[k] += b[k] * b[k];
        }
    }
    let relative = (0..3).map(|k| (rr[k] / bb[k]).sqrt()).fold(0.0, f64::max);
    assert!(relative <= 1.01e-11, "recomputed relative residual {relative:e}");
    assert!((relative - ext.residual).abs() <= 1e-3 * ext.residual + 1e-15);
}

#[test]
fn the_extension_does_not_depend_on_the_number_of_threads() {
    // A thicker shell of ~61 k free voxels: fifteen reduction chunks.
    let grid = Grid::axis_aligned([60, 60, 60], [1.0; 3], [-29.5; 3]).unwrap();
    let r = |n: usize| grid.world(idx(&grid, n)).coords.norm();
    let free: Vec<bool> = (0..grid.len()).map(|n| (10.0..25.0).contains(&r(n))).collect();
    assert!(free.iter().filter(|&&f| f).count() > 10 * 4096);
    let f = |n: usize| {
        let p = grid.world(idx(&grid, n));
        if r(n) < 10.0 { [p.y, -p.x, 0.5] } else { [0.0; 3] }
    };
    let params = ExtensionParams::default();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| harmonic_extension(&grid, &free, &f, &params))
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.iterations, two.iterations);
    assert_eq!(one.values, two.values, "bit-identical values");
}

#[test]
fn indices_where_lists_the_true_flags_in_order() {
    // Across several parallel chunks (2^16 flags each) and a partial last one.
    let flags: Vec<bool> = (0..200_003usize).map(|n| n % 7 == 3 || n % 65_536 == 0).collect();
    let expect: Vec<u32> = (0..flags.len()).filter(|&n| flags[n]).map(|n| n as u32).collect();
    assert_eq!(indices_where(&flags), expect);
    assert!(indices_where(&[false; 10]).is_empty());
}
