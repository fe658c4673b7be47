//! The linearised equilibrium in the mixed form of the nearly incompressible split
//! ([`VolumetricSplit`]): GMRES on displacements and multipliers, the multiplier's volumetric
//! term moved to the linearisation point, the block preconditioned by the split's own
//! multilevel cycle under the solve's constraints.

use std::time::{Duration, Instant};

use bs_mesh::{Point3, Vector3};

use crate::assembly::VolumetricScratch;
use crate::linalg::krylov::{Gmres, GmresInfo, NodalMap};
use crate::linalg::multilevel::{
    Constraints, Multilevel, MultilevelScratch, SplitScratch, VolumetricSplit,
};
use crate::linalg::sparse::RankOneSum;
use crate::model::Model;

/// A split and the preconditioner of its block ([`Multilevel::split`]).
pub(crate) type Split<'a> = (&'a VolumetricSplit, &'a Multilevel);

/// Stopping rule of a linear solve.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tolerance {
    pub rtol: f64,
    pub max_iterations: usize,
}

/// Buffers of a solve in the mixed form, made at the first one.
#[derive(Debug)]
pub(crate) struct MixedBuffers {
    gmres: Gmres,
    rhs: Vec<Vector3<f64>>,
    /// The solution: displacements, then the multipliers.
    pub x: Vec<Vector3<f64>>,
    apply: SplitScratch,
    precondition: SplitScratch,
    tl: MultilevelScratch,
    /// The volumetric term at the linearisation point.
    term: RankOneSum,
    positions: Vec<Point3<f64>>,
    volumetric: VolumetricScratch,
}

impl MixedBuffers {
    fn new((split, block): Split<'_>, n: usize, restart: usize) -> Self {
        let len = split.len(n);
        MixedBuffers {
            gmres: Gmres::new(len, restart),
            rhs: vec![Vector3::zeros(); len],
            x: vec![Vector3::zeros(); len],
            apply: SplitScratch::default(),
            precondition: SplitScratch::default(),
            tl: block.scratch(),
            term: split.term(),
            positions: Vec::new(),
            volumetric: VolumetricScratch::default(),
        }
    }

    /// The buffers in `slot` (made or remade for `split`), with the volumetric term moved
    /// to `X + u`, when the mixed form pays there ([`VolumetricSplit::pays`]).
    pub(crate) fn at<'a>(
        slot: &'a mut Option<MixedBuffers>,
        split: Split<'_>,
        model: &Model,
        u: &[Vector3<f64>],
        restart: usize,
    ) -> Option<&'a mut MixedBuffers> {
        let n = u.len();
        if slot.as_ref().is_none_or(|m| m.gmres.len() != split.0.len(n)) {
            *slot = Some(MixedBuffers::new(split, n, restart));
        }
        let mixed = slot.as_mut()?;
        mixed.positions.clear();
        mixed.positions.extend(model.reference().iter().zip(u).map(|(p, d)| p + d));
        let (x, term, scratch) = (&mixed.positions, &mut mixed.term, &mut mixed.volumetric);
        let dj = model.volumetric_at(x, term, split.0.above(), scratch)?;
        split.0.pays(dj).then_some(mixed)
    }

    /// Solves the mixed form of `J δ = rhs` (`op` applying `Π J`) into [`x`](Self::x);
    /// the block's preconditioner time is added to `prec_time`.
    pub(crate) fn solve(
        &mut self,
        (split, block): Split<'_>,
        cons: &Constraints,
        rhs: &[Vector3<f64>],
        op: &mut NodalMap<'_>,
        tol: Tolerance,
        prec_time: &mut Duration,
    ) -> GmresInfo {
        let n = rhs.len();
        let pi = &cons.projector;
        self.rhs[..n].copy_from_slice(rhs);
        self.rhs[n..].iter_mut().for_each(|v| *v = Vector3::zeros());
        let moved = split.moved(&mut self.term);
        let block_cons = block.constraints_like(cons);
        let (tl, apply, precondition) = (&mut self.tl, &mut self.apply, &mut self.precondition);
        let mut block_prec = |r: &[Vector3<f64>], z: &mut [Vector3<f64>]| {
            let t = Instant::now();
            block.apply(&block_cons, r, z, tl);
            *prec_time += t.elapsed();
        };
        let mut mop = |v: &[Vector3<f64>], out: &mut [Vector3<f64>]| {
            moved.apply(pi, n, v, out, apply, op);
        };
        let mut mprec = |r: &[Vector3<f64>], z: &mut [Vector3<f64>]| {
            moved.precondition(pi, n, r, z, precondition, &mut block_prec);
        };
        self.gmres.solve(&mut mop, &mut mprec, &self.rhs, &mut self.x, tol.rtol, tol.max_iterations)
    }
}
