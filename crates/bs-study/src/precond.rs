//! The Newton–Krylov preconditioner measured on its own, for `cargo xtask bench solver`: the
//! two-level method against the multilevel hierarchy on a scene's `K₀` (the levels and their
//! unknowns, the GMRES iterations of a linear solve, the time of one cycle and the bytes it
//! moves), beside the machine's memory bandwidth measured in the same process by a
//! stream-like triad, so that the distance of a cycle to the memory floor is one number.

use std::path::Path;
use std::time::Instant;

use bs_dr::linalg::krylov::Gmres;
use bs_dr::linalg::sparse::dot;
use bs_mesh::Vector3;
use bs_scene::Prepared;
use bs_scene::compose::compose;
use bs_scene::solve::{SolveSettings, prepare_solver};
use rayon::prelude::*;

/// One preconditioner on one scene's `K₀`.
#[derive(Debug, Clone)]
pub struct Cycle {
    /// Unknowns of every coarse level (the first coarse level first, the factorised last).
    pub levels: Vec<usize>,
    /// Seconds of the setup (the whole preparation of the solver).
    pub setup: f64,
    /// GMRES iterations of `K₀ x = b` to a relative residual of 1e-8 (restart 40).
    pub gmres: usize,
    /// Seconds per cycle (best of five batches).
    pub seconds: f64,
    /// Bytes one cycle moves (`Multilevel::bytes_per_cycle`).
    pub bytes: usize,
    /// Nodes of the mesh.
    pub nodes: usize,
}

/// The preconditioner of `scene`'s Newton–Krylov preparation with at most `max_levels`
/// levels, measured (see the module documentation).
pub fn measure(scene: &Path, max_levels: usize) -> Result<Cycle, String> {
    let p = Prepared::load(scene).map_err(|e| e.to_string())?;
    let mut c = compose(&p).map_err(|e| e.to_string())?;
    let settings = SolveSettings { max_levels: Some(max_levels), ..SolveSettings::of(&p) };
    let t = Instant::now();
    prepare_solver(&mut c, &settings).map_err(|e| e.to_string())?;
    let setup = t.elapsed().as_secs_f64();
    let prep = c.preparation.as_ref().ok_or("no Newton–Krylov preparation")?;
    let tl = prep.preconditioner();
    let k = tl.operator().ok_or("the preparation kept no operator")?;
    let con = tl.constraints();
    let fixed = &con.projector;
    let n = c.model.node_count();
    // A smooth right-hand side: K₀ of a shear and a bend, without the fixed components.
    let mut u: Vec<Vector3<f64>> = c
        .model
        .reference()
        .iter()
        .map(|x| Vector3::new(0.01 * x.z, 0.001 * x.x, -0.01 * x.x))
        .collect();
    fixed.apply(&mut u);
    let mut ks = k.scratch();
    let mut b = vec![Vector3::zeros(); n];
    k.mul(&u, &mut b, &mut ks);
    fixed.apply(&mut b);
    let mut ts = tl.scratch();
    let mut op = |x: &[Vector3<f64>], y: &mut [Vector3<f64>]| {
        k.mul(x, y, &mut ks);
        fixed.apply(y);
    };
    let mut prec = |r: &[Vector3<f64>], z: &mut [Vector3<f64>]| tl.apply(&con, r, z, &mut ts);
    let mut x = vec![Vector3::zeros(); n];
    let info = Gmres::new(n, 40).solve(&mut op, &mut prec, &b, &mut x, 1e-8, 2000);
    let mut ts = tl.scratch();
    let mut z = vec![Vector3::zeros(); n];
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        for _ in 0..10 {
            tl.apply(&con, &b, &mut z, &mut ts);
        }
        best = best.min(t.elapsed().as_secs_f64() / 10.0);
    }
    // Keep the result observable.
    if !dot(&z, &b).is_finite() {
        return Err("the cycle returned a non-finite vector".into());
    }
    let (levels, _, _) = tl.sizes();
    Ok(Cycle {
        levels,
        setup,
        gmres: info.iterations,
        seconds: best,
        bytes: tl.bytes_per_cycle(),
        nodes: n,
    })
}

/// The machine's memory bandwidth in bytes per second: `a = b + s c` over three arrays of
/// 32 MiB each (beyond the caches), on the rayon pool, best of five; 24 bytes per entry.
pub fn stream_bandwidth() -> f64 {
    let len = 4 << 20;
    let b = vec![1.0f64; len];
    let c = vec![2.0f64; len];
    let mut a = vec![0.0f64; len];
    let mut best = f64::INFINITY;
    for round in 0..6 {
        let s = 0.5 + round as f64;
        let t = Instant::now();
        a.par_chunks_mut(1 << 16).zip(b.par_chunks(1 << 16).zip(c.par_chunks(1 << 16))).for_each(
            |(a, (b, c))| {
                for ((x, y), z) in a.iter_mut().zip(b).zip(c) {
                    *x = y + s * z;
                }
            },
        );
        if round > 0 {
            best = best.min(t.elapsed().as_secs_f64());
        }
    }
    std::hint::black_box(&a);
    (24 * len) as f64 / best
}
