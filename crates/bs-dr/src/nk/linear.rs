//! The linearised equilibrium of one Newton iteration, `Π J Π δ = −Π (f + J u_p)`, solved by
//! GMRES with the multilevel preconditioner. `J` is applied matrix-free as a forward
//! difference of the internal forces (so every element technology is linearised exactly as
//! its force kernel); `u_p` is the particular displacement (prescribed values still to apply
//! and the normal moves that put held contact nodes on their features); `Π` removes fixed
//! and held directions. Nearly incompressible T4ANP models are solved in the mixed form of
//! [`super::mixed`] where it pays.

use std::time::{Duration, Instant};

use bs_mesh::Vector3;
use rayon::prelude::*;

use super::Work;
use super::mixed::{MixedBuffers, Tolerance};
use crate::assembly::{Inversion, Workspace};
use crate::data::Springs;
use crate::linalg::krylov::{Gmres, GmresInfo};
use crate::linalg::multilevel::{Constraints, Multilevel, MultilevelScratch};
use crate::linalg::sparse::max_abs;
use crate::model::Model;

/// The forces of the energy the solve minimises at `u`: the internal forces plus the data
/// springs of the current linearisation (none without measurements) minus the dead forces
/// `dead` (a body force, in full; empty without one), with the count and time kept.
pub(crate) fn forces(
    model: &Model,
    (data, dead): (&Springs, &[Vector3<f64>]),
    u: &[Vector3<f64>],
    ws: &mut Workspace,
    f: &mut [Vector3<f64>],
    work: &mut Work,
) -> Result<(), Inversion> {
    let t = Instant::now();
    work.forces += 1;
    let r = model.internal_forces_into(u, ws, f);
    if r.is_ok() && !data.is_empty() {
        data.add_forces_into(model.reference(), u, 1.0, f);
    }
    if r.is_ok() {
        f.iter_mut().zip(dead).for_each(|(fi, e)| *fi -= e);
    }
    work.time.forces += t.elapsed();
    r
}

/// Buffers of [`solve`], sized once per solve.
#[derive(Debug)]
pub(crate) struct LinearBuffers {
    pub up: Vec<Vector3<f64>>,
    pub fd: Vec<Vector3<f64>>,
    pub rhs: Vec<Vector3<f64>>,
    pub gmres: Gmres,
    pub tl: MultilevelScratch,
    /// The mixed form's buffers, made at the first solve with a split preconditioner.
    pub mixed: Option<MixedBuffers>,
}

/// The linearisation point and what is held there.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Linearisation<'a> {
    pub model: &'a Model,
    /// The data springs of the iteration (their Jacobian enters through the difference).
    pub data: &'a Springs,
    /// The dead forces (empty: none).
    pub dead: &'a [Vector3<f64>],
    pub u: &'a [Vector3<f64>],
    pub f: &'a [Vector3<f64>],
    pub particular: &'a [Vector3<f64>],
    /// Tangential springs of held nodes on curved features: `(node, stiffness)`.
    pub springs: &'a [(usize, f64)],
    pub cons: &'a Constraints,
    pub tl: &'a Multilevel,
    /// The force change whose displacement response is sought (`None`: the Newton step's
    /// right-hand side `−Π (f + J u_p)`; the linear response of `nk/response.rs`).
    pub load: Option<&'a [Vector3<f64>]>,
    /// Whether GMRES ends after a restart cycle that stalled: under a body force alone
    /// (nothing prescribed moves), where a brain that floats before the skull holds it has
    /// a nearly singular tangent and restarted GMRES stalls (docs/decisions.md).
    pub stall_exit: bool,
}

/// `out = Π J v` at the linearisation point, `J` the forward difference of the forces
/// (`umax` the largest displacement component of `lin.u`; `up` a buffer of the model's
/// length). A direction that inverts an element within the difference step is treated as
/// infinitely stiff (`out = 10³⁰ v`: a Krylov method then leaves it alone).
pub(crate) fn tangent_product(
    lin: &Linearisation<'_>,
    umax: f64,
    (up, ws): (&mut [Vector3<f64>], &mut Workspace),
    work: &mut Work,
    v: &[Vector3<f64>],
    out: &mut [Vector3<f64>],
) {
    let (u, f) = (lin.u, lin.f);
    let vmax = max_abs(v);
    if vmax == 0.0 {
        out.iter_mut().for_each(|o| *o = Vector3::zeros());
        return;
    }
    let h = 1e-7 * (1.0 + umax) / vmax;
    up.par_iter_mut().zip(u.par_iter()).zip(v.par_iter()).for_each(|((w, a), d)| {
        *w = a + d * h;
    });
    match forces(lin.model, (lin.data, lin.dead), up, ws, out, work) {
        Ok(()) => {
            out.par_iter_mut().zip(f.par_iter()).for_each(|(o, f0)| *o = (*o - f0) / h);
            for &(a, k) in lin.springs {
                out[a] += v[a] * k;
            }
            lin.cons.projector.apply(out);
        }
        Err(_) => out.iter_mut().zip(v).for_each(|(o, vi)| *o = vi * 1e30),
    }
}

/// Solves for `delta` to the relative residual `rtol` (at most `max_iterations` GMRES
/// iterations); `Err` when the particular displacement itself inverts an element within the
/// difference step.
pub(crate) fn solve(
    lin: &Linearisation<'_>,
    b: &mut LinearBuffers,
    ws: &mut Workspace,
    delta: &mut [Vector3<f64>],
    rtol: f64,
    max_iterations: usize,
    work: &mut Work,
) -> Result<GmresInfo, Inversion> {
    let (model, data, u, f) = (lin.model, (lin.data, lin.dead), lin.u, lin.f);
    let pi = &lin.cons.projector;
    // Right-hand side −Π (f + J u_p).
    let pmax = max_abs(lin.particular);
    let umax = max_abs(u);
    if let Some(load) = lin.load {
        b.rhs.par_iter_mut().zip(load.par_iter()).for_each(|(r, l)| *r = *l);
    } else if pmax > 0.0 {
        let h = 1e-7 * (1.0 + umax) / pmax;
        b.up.par_iter_mut()
            .zip(u.par_iter())
            .zip(lin.particular.par_iter())
            .for_each(|((w, a), p)| *w = a + p * h);
        forces(model, data, &b.up, ws, &mut b.fd, work)?;
        b.rhs.par_iter_mut().zip(f.par_iter()).zip(b.fd.par_iter()).for_each(|((r, f0), f1)| {
            *r = -(f0 + (f1 - f0) / h);
        });
    } else {
        b.rhs.par_iter_mut().zip(f.par_iter()).for_each(|(r, f0)| *r = -f0);
    }
    pi.apply(&mut b.rhs);
    let up = &mut b.up;
    let mut op = |v: &[Vector3<f64>], out: &mut [Vector3<f64>]| {
        tangent_product(lin, umax, (up, &mut *ws), work, v, out);
    };
    let mut prec_time = Duration::ZERO;
    let (tl, cons, scratch) = (lin.tl, lin.cons, &mut b.tl);
    let mut prec = |r: &[Vector3<f64>], z: &mut [Vector3<f64>]| {
        let t = Instant::now();
        tl.apply(cons, r, z, scratch);
        prec_time += t.elapsed();
    };
    let mixed_form = tl.split().and_then(|split| {
        let mixed = MixedBuffers::at(&mut b.mixed, split, model, u, b.gmres.restart())?;
        Some((split, mixed))
    });
    let info = match mixed_form {
        None => {
            b.gmres.set_stall_exit(lin.stall_exit);
            b.gmres.solve(&mut op, &mut prec, &b.rhs, delta, rtol, max_iterations)
        }
        Some((split, mixed)) => {
            let tol = Tolerance { rtol, max_iterations };
            let info = mixed.solve(split, cons, &b.rhs, &mut op, tol, &mut prec_time);
            delta.copy_from_slice(&mixed.x[..delta.len()]);
            info
        }
    };
    work.linear += info.iterations;
    work.time.preconditioner += prec_time;
    pi.apply(delta);
    Ok(info)
}
