//! Exact Euclidean distance transform on a voxel grid (Felzenszwalb & Huttenlocher,
//! "Distance Transforms of Sampled Functions", 2012): the lower envelope of parabolas, one
//! axis at a time, with the voxel spacing of each axis.

use rayon::prelude::*;

/// Squared distance (mm²) from every voxel centre to the nearest voxel where `feature` is
/// true; `f32::INFINITY` if there is none. `spacing` is the voxel size along each axis (the
/// axes are taken as orthogonal).
pub fn squared_distance(feature: &[bool], dims: [usize; 3], spacing: [f64; 3]) -> Vec<f32> {
    let [nx, ny, nz] = dims;
    let mut d: Vec<f32> =
        feature.par_iter().map(|&f| if f { 0.0 } else { f32::INFINITY }).collect();
    let w2 = spacing.map(|s| (s * s) as f32);
    // x rows.
    d.par_chunks_mut(nx).for_each_init(
        || Scratch::new(nx),
        |s, row| {
            s.input[..nx].copy_from_slice(row);
            s.transform(nx, w2[0]);
            row.copy_from_slice(&s.output[..nx]);
        },
    );
    // y columns within each z slab.
    d.par_chunks_mut(nx * ny).for_each_init(
        || Scratch::new(ny),
        |s, slab| {
            for i in 0..nx {
                for j in 0..ny {
                    s.input[j] = slab[i + nx * j];
                }
                s.transform(ny, w2[1]);
                for j in 0..ny {
                    slab[i + nx * j] = s.output[j];
                }
            }
        },
    );
    // z columns: transformed per y (gathered), then written back.
    let src = &d;
    let cols: Vec<Vec<f32>> = (0..ny)
        .into_par_iter()
        .map_init(
            || Scratch::new(nz),
            |s, j| {
                let mut out = vec![0f32; nx * nz];
                for i in 0..nx {
                    for k in 0..nz {
                        s.input[k] = src[i + nx * (j + ny * k)];
                    }
                    s.transform(nz, w2[2]);
                    out[i * nz..(i + 1) * nz].copy_from_slice(&s.output[..nz]);
                }
                out
            },
        )
        .collect();
    for (j, col) in cols.iter().enumerate() {
        for i in 0..nx {
            for k in 0..nz {
                d[i + nx * (j + ny * k)] = col[i * nz + k];
            }
        }
    }
    d
}

struct Scratch {
    input: Vec<f32>,
    output: Vec<f32>,
    v: Vec<usize>,
    z: Vec<f32>,
}

impl Scratch {
    fn new(n: usize) -> Scratch {
        Scratch { input: vec![0.0; n], output: vec![0.0; n], v: vec![0; n], z: vec![0.0; n + 1] }
    }

    /// 1-D squared distance transform of `input[..n]` with squared spacing `w2`.
    fn transform(&mut self, n: usize, w2: f32) {
        let f = &self.input;
        let Some(first) = f[..n].iter().position(|x| x.is_finite()) else {
            self.output[..n].fill(f32::INFINITY);
            return;
        };
        let (v, z) = (&mut self.v, &mut self.z);
        let mut k = 0usize;
        v[0] = first;
        z[0] = f32::NEG_INFINITY;
        z[1] = f32::INFINITY;
        for q in first + 1..n {
            if !f[q].is_finite() {
                continue;
            }
            let qf = q as f32;
            loop {
                let p = v[k];
                let pf = p as f32;
                let s = ((f[q] + w2 * qf * qf) - (f[p] + w2 * pf * pf)) / (2.0 * w2 * (qf - pf));
                if s <= z[k] && k > 0 {
                    k -= 1;
                    continue;
                }
                if s <= z[k] {
                    // k == 0: the new parabola dominates everywhere.
                    v[0] = q;
                    z[0] = f32::NEG_INFINITY;
                    z[1] = f32::INFINITY;
                    break;
                }
                k += 1;
                v[k] = q;
                z[k] = s;
                z[k + 1] = f32::INFINITY;
                break;
            }
        }
        let mut k = 0usize;
        for q in 0..n {
            let qf = q as f32;
            while z[k + 1] < qf {
                k += 1;
            }
            let p = v[k];
            let dq = qf - p as f32;
            self.output[q] = w2 * dq * dq + f[p];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against brute force on a small random set with anisotropic spacing.
    #[test]
    fn matches_brute_force() {
        let dims = [7, 6, 5];
        let sp = [1.0, 0.7, 1.6];
        let n = 7 * 6 * 5;
        let mut rng = bs_mesh::rng::SplitMix64::new(3);
        let feature: Vec<bool> = (0..n).map(|_| rng.below(9) == 0).collect();
        let d = squared_distance(&feature, dims, sp);
        for k in 0..5 {
            for j in 0..6 {
                for i in 0..7 {
                    let mut best = f64::INFINITY;
                    for c in 0..5 {
                        for b in 0..6 {
                            for a in 0..7 {
                                if feature[a + 7 * (b + 6 * c)] {
                                    let dx = (a as f64 - i as f64) * sp[0];
                                    let dy = (b as f64 - j as f64) * sp[1];
                                    let dz = (c as f64 - k as f64) * sp[2];
                                    best = best.min(dx * dx + dy * dy + dz * dz);
                                }
                            }
                        }
                    }
                    let got = d[i + 7 * (j + 6 * k)] as f64;
                    assert!((got - best).abs() < 1e-3 * (1.0 + best), "{got} vs {best}");
                }
            }
        }
    }
}
