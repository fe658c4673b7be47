//! The inner solve: `A e = r` for the three components at once by conjugate gradients with
//! a diagonal (Jacobi) preconditioner, in single precision (the vectors of a 260 k-voxel gap
//! then fit in a 32 MB cache twice over; every reduction is accumulated in double
//! precision and summed in fixed chunks, so the result does not depend on the number of
//! threads). Three fused passes per iteration: `A p` with `p·Ap`; `e`, `r` updated with
//! `r·z` and `r·r`; `p`.

use rayon::prelude::*;

use super::stencil::Stencil;

/// Chunk of the fixed-order reductions.
pub(super) const CHUNK: usize = 4096;

/// Per-component sums of fixed chunks, added in chunk order.
pub(super) fn sum3(parts: &[[f64; 3]]) -> [f64; 3] {
    parts.iter().fold([0.0; 3], |s, p| [s[0] + p[0], s[1] + p[1], s[2] + p[2]])
}

/// Squared norms of the three components.
pub(super) fn norm2<T: Copy + Into<f64> + Sync>(v: &[[T; 3]]) -> [f64; 3] {
    let parts: Vec<[f64; 3]> = v
        .par_chunks(CHUNK)
        .map(|c| {
            c.iter().fold([0.0; 3], |s, x| {
                let x: [f64; 3] = x.map(Into::into);
                [s[0] + x[0] * x[0], s[1] + x[1] * x[1], s[2] + x[2] * x[2]]
            })
        })
        .collect();
    sum3(&parts)
}

/// What the inner solve did.
pub(super) struct Inner {
    /// The correction.
    pub e: Vec<[f32; 3]>,
    pub iterations: usize,
}

/// Solves `A e = r` from `e = 0` until every component's residual norm is at most
/// `target[c]` (by the recurrence), or after `max_iterations`.
pub(super) fn solve(st: &Stencil, mut r: Vec<[f32; 3]>, target: [f64; 3], max: usize) -> Inner {
    let m = st.len();
    let d = &st.diag32;
    let mut e = vec![[0.0f32; 3]; m];
    let mut p: Vec<[f32; 3]> = r.iter().zip(d).map(|(r, d)| r.map(|x| x / d)).collect();
    let parts: Vec<([f64; 3], [f64; 3])> = r
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(k, c)| {
            let (mut rz, mut rr) = ([0.0; 3], [0.0; 3]);
            for (j, ri) in c.iter().enumerate() {
                let dj = f64::from(d[k * CHUNK + j]);
                for q in 0..3 {
                    let x = f64::from(ri[q]);
                    rz[q] += x * x / dj;
                    rr[q] += x * x;
                }
            }
            (rz, rr)
        })
        .collect();
    let mut rz = sum3(&parts.iter().map(|s| s.0).collect::<Vec<_>>());
    let mut rr = sum3(&parts.iter().map(|s| s.1).collect::<Vec<_>>());
    let done = |rr: &[f64; 3]| (0..3).all(|c| rr[c].sqrt() <= target[c]);
    let mut ap = vec![[0.0f32; 3]; m];
    let mut iterations = 0;
    while !done(&rr) && iterations < max {
        let parts: Vec<[f64; 3]> = ap
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(k, out)| {
                let mut s = [0.0; 3];
                for (j, o) in out.iter_mut().enumerate() {
                    let i = k * CHUNK + j;
                    *o = st.row32(i, &p);
                    for c in 0..3 {
                        s[c] += f64::from(p[i][c]) * f64::from(o[c]);
                    }
                }
                s
            })
            .collect();
        let pap = sum3(&parts);
        let alpha = [0, 1, 2].map(|c| if pap[c] > 0.0 { (rz[c] / pap[c]) as f32 } else { 0.0 });
        let parts: Vec<([f64; 3], [f64; 3])> = e
            .par_chunks_mut(CHUNK)
            .zip(r.par_chunks_mut(CHUNK))
            .enumerate()
            .map(|(k, (ec, rc))| {
                let (mut rzs, mut rrs) = ([0.0; 3], [0.0; 3]);
                for (j, (ei, ri)) in ec.iter_mut().zip(rc.iter_mut()).enumerate() {
                    let i = k * CHUNK + j;
                    let dj = f64::from(d[i]);
                    for c in 0..3 {
                        ei[c] += alpha[c] * p[i][c];
                        ri[c] -= alpha[c] * ap[i][c];
                        let x = f64::from(ri[c]);
                        rzs[c] += x * x / dj;
                        rrs[c] += x * x;
                    }
                }
                (rzs, rrs)
            })
            .collect();
        let rz_new = sum3(&parts.iter().map(|s| s.0).collect::<Vec<_>>());
        rr = sum3(&parts.iter().map(|s| s.1).collect::<Vec<_>>());
        let beta = [0, 1, 2].map(|c| if rz[c] > 0.0 { (rz_new[c] / rz[c]) as f32 } else { 0.0 });
        rz = rz_new;
        p.par_chunks_mut(CHUNK).zip(r.par_chunks(CHUNK)).enumerate().for_each(|(k, (pc, rc))| {
            for (j, (pi, ri)) in pc.iter_mut().zip(rc).enumerate() {
                let dj = d[k * CHUNK + j];
                for c in 0..3 {
                    pi[c] = ri[c] / dj + beta[c] * pi[c];
                }
            }
        });
        iterations += 1;
    }
    Inner { e, iterations }
}
