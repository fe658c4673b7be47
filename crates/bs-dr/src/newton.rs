//! Static Newton–Raphson reference solver: load stepping, backtracking line search, sparse
//! tangent stiffness assembled on the free DOFs and factorised with faer's sparse Cholesky
//! (symbolic factorisation computed once and reused).
//!
//! Supported elements: T4 and H8 (mean strain + hourglass stiffness). T4ANP's nodal
//! averaging couples neighbouring elements in the tangent and is not supported (use DR).
//! Contact is not supported: after convergence the contact handler is called once, and if it
//! reports nodes in contact the solve fails with [`SolveError::Unsupported`].

use std::time::Instant;

use bs_mesh::{Point3, Vector3};
use faer::Mat;
use faer::Side;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{Pair, SparseColMat, SymbolicSparseColMat};

use crate::assembly::tangent::element_tangent;
use crate::contact::Contact;
use crate::loads::Loads;
use crate::model::Model;
use crate::solver::{Progress, Report, Solution, SolveError, Solver, check_param, load_scale};

/// Parameters of [`Newton`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonParams {
    /// Number of equal load steps. Default 10.
    pub load_steps: usize,
    /// Convergence tolerance on `max|δu|` relative to the load scale. Default 1e-10.
    pub tolerance: f64,
    /// Iterations allowed per load step. Default 30.
    pub max_iterations: usize,
    /// Backtracking line search on the residual norm. Default true.
    pub line_search: bool,
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams { load_steps: 10, tolerance: 1e-10, max_iterations: 30, line_search: true }
    }
}

/// The static Newton–Raphson solver.
#[derive(Debug, Clone, Copy, Default)]
pub struct Newton {
    /// Parameters.
    pub params: NewtonParams,
}

impl Newton {
    /// A solver with the given parameters.
    pub fn new(params: NewtonParams) -> Self {
        Newton { params }
    }
}

impl Solver for Newton {
    fn name(&self) -> &'static str {
        "newton"
    }

    fn solve(
        &self,
        model: &Model,
        loads: &Loads,
        contact: &mut dyn Contact,
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solution, SolveError> {
        let p = self.params;
        check_param("load_steps", p.load_steps as f64, p.load_steps >= 1, "must be >= 1")?;
        check_param("tolerance", p.tolerance, p.tolerance > 0.0, "must be > 0")?;
        check_param(
            "max_iterations",
            p.max_iterations as f64,
            p.max_iterations >= 1,
            "must be >= 1",
        )?;
        let n = model.node_count();
        if loads.node_count() != n {
            return Err(SolveError::LoadMismatch { expected: n, got: loads.node_count() });
        }
        if model.elements.anp() {
            return Err(SolveError::Unsupported {
                solver: "newton",
                what: "T4ANP tetrahedra",
                fix: "use TetFormulation::T4 or the Dynamic Relaxation solver",
            });
        }
        let start = Instant::now();
        let scale = load_scale(model, loads);
        let tol = p.tolerance * scale;
        let (free, fixed) = loads.split_dofs();
        let nf = free.len();
        let mut dof_map = vec![usize::MAX; 3 * n];
        for (i, &d) in free.iter().enumerate() {
            dof_map[d] = i;
        }
        // Sparsity pattern (lower triangle, duplicates summed by faer).
        let mut pairs = Vec::new();
        for (_, e) in model.elements.iter() {
            for &na in e.nodes {
                for &nb in e.nodes {
                    for i in 0..3 {
                        for j in 0..3 {
                            let (r, c) =
                                (dof_map[3 * na as usize + i], dof_map[3 * nb as usize + j]);
                            if r != usize::MAX && c != usize::MAX && r >= c {
                                pairs.push(Pair { row: r, col: c });
                            }
                        }
                    }
                }
            }
        }
        let (symbolic, argsort) =
            SymbolicSparseColMat::<usize>::try_new_from_indices(nf, nf, &pairs)
                .map_err(|_| SolveError::SingularTangent { load_step: 0, iteration: 0 })?;
        let sym_llt = SymbolicLlt::try_new(symbolic.as_ref(), Side::Lower)
            .map_err(|_| SolveError::SingularTangent { load_step: 0, iteration: 0 })?;
        let mut values = vec![0.0; pairs.len()];

        let mut u = vec![Vector3::<f64>::zeros(); n];
        let mut trial = u.clone();
        let mut forces = u.clone();
        let mut ws = model.workspace();
        let mut ke = vec![0.0; 24 * 24];
        let mut rhs = Mat::<f64>::zeros(nf, 1);
        let mut dp = vec![0.0; 3 * n];
        let mut iterations = 0usize;
        let mut force_evaluations = 0usize;
        let mut last_err = f64::INFINITY;

        let residual_norm = |f: &[Vector3<f64>]| -> f64 {
            free.iter().map(|&d| f[d / 3][d % 3].powi(2)).sum::<f64>().sqrt()
        };

        for ls in 1..=p.load_steps {
            let lf = ls as f64 / p.load_steps as f64;
            let lf_prev = (ls - 1) as f64 / p.load_steps as f64;
            dp.iter_mut().for_each(|v| *v = 0.0);
            for &d in &fixed {
                dp[d] = loads.value(d / 3, d % 3) * (lf - lf_prev);
            }
            let mut converged = false;
            for it in 1..=p.max_iterations {
                iterations += 1;
                // Residual at u and tangent assembly (+ K_fp dp on the first iteration).
                force_evaluations += 1;
                if let Err(inv) = model.internal_forces_into(&u, &mut ws, &mut forces) {
                    return Err(SolveError::ElementInverted {
                        step: iterations,
                        element: inv.element,
                        element_id: inv.element_id,
                        jacobian: inv.jacobian,
                    });
                }
                for (i, &d) in free.iter().enumerate() {
                    rhs[(i, 0)] = -forces[d / 3][d % 3];
                }
                let mut pos = 0;
                for (_, e) in model.elements.iter() {
                    let nn = e.nodes.len();
                    let n3 = 3 * nn;
                    let material = &model.elements.solids[e.mat].material;
                    if !element_tangent(material, &e, &u, &mut ke[..n3 * n3]) {
                        return Err(SolveError::SingularTangent { load_step: ls, iteration: it });
                    }
                    for a in 0..nn {
                        for b in 0..nn {
                            for i in 0..3 {
                                for j in 0..3 {
                                    let gr = 3 * e.nodes[a] as usize + i;
                                    let gc = 3 * e.nodes[b] as usize + j;
                                    let (r, c) = (dof_map[gr], dof_map[gc]);
                                    let v = ke[(3 * a + i) * n3 + 3 * b + j];
                                    if r != usize::MAX && c != usize::MAX && r >= c {
                                        values[pos] = v;
                                        pos += 1;
                                    }
                                    if it == 1 && r != usize::MAX && c == usize::MAX {
                                        rhs[(r, 0)] -= v * dp[gc];
                                    }
                                }
                            }
                        }
                    }
                }
                debug_assert_eq!(pos, values.len());
                let kmat = SparseColMat::new_from_argsort(symbolic.clone(), &argsort, &values)
                    .map_err(|_| SolveError::SingularTangent { load_step: ls, iteration: it })?;
                let llt = Llt::try_new_with_symbolic(sym_llt.clone(), kmat.as_ref(), Side::Lower)
                    .map_err(|_| SolveError::SingularTangent {
                    load_step: ls,
                    iteration: it,
                })?;
                llt.solve_in_place(rhs.as_mut());
                // Line search on the free-DOF residual norm, compared with the residual of
                // the state with only the prescribed increment applied.
                let base_u = u.clone();
                let ref_norm = if p.line_search {
                    trial.copy_from_slice(&base_u);
                    if it == 1 {
                        for &d in &fixed {
                            trial[d / 3][d % 3] += dp[d];
                        }
                    }
                    force_evaluations += 1;
                    match model.internal_forces_into(&trial, &mut ws, &mut forces) {
                        Ok(()) => residual_norm(&forces),
                        Err(_) => f64::INFINITY,
                    }
                } else {
                    f64::INFINITY
                };
                let mut alpha = 1.0;
                let mut accepted = false;
                for _ in 0..12 {
                    trial.copy_from_slice(&base_u);
                    for (i, &d) in free.iter().enumerate() {
                        trial[d / 3][d % 3] += alpha * rhs[(i, 0)];
                    }
                    if it == 1 {
                        for &d in &fixed {
                            trial[d / 3][d % 3] += dp[d];
                        }
                    }
                    if !p.line_search {
                        accepted = true;
                        break;
                    }
                    force_evaluations += 1;
                    if model.internal_forces_into(&trial, &mut ws, &mut forces).is_ok() {
                        let rn = residual_norm(&forces);
                        if rn <= ref_norm * (1.0 + 1e-9) || alpha < 1e-3 {
                            accepted = true;
                            break;
                        }
                    }
                    alpha *= 0.5;
                }
                if !accepted {
                    return Err(SolveError::NoConvergence {
                        err: last_err,
                        steps: iterations,
                        tolerance: tol,
                    });
                }
                u.copy_from_slice(&trial);
                // Full Newton correction (before the line-search scaling) measures convergence.
                let step_max = (0..nf).fold(0.0f64, |a, i| a.max(rhs[(i, 0)].abs()));
                last_err = step_max;
                let maxu = u.iter().fold(0.0f64, |a, v| a.max(v.norm()));
                observer(&Progress {
                    step: iterations,
                    err: step_max,
                    rho: 0.0,
                    load_factor: lf,
                    max_displacement: maxu,
                    contact: Default::default(),
                    linear_iterations: 0,
                    force_evaluations,
                });
                if !step_max.is_finite() {
                    return Err(SolveError::NotFinite { step: iterations });
                }
                if it > 1 && step_max <= tol {
                    converged = true;
                    break;
                }
            }
            if !converged {
                return Err(SolveError::NoConvergence {
                    err: last_err,
                    steps: iterations,
                    tolerance: tol,
                });
            }
        }
        // Contact is not supported: fail if the answer violates the constraint.
        let mut positions: Vec<Point3<f64>> =
            model.reference().iter().zip(&u).map(|(x, d)| x + d).collect();
        let report = contact.enforce(&mut positions);
        if report.nodes_in_contact > 0 {
            return Err(SolveError::Unsupported {
                solver: "newton",
                what: "contact (the converged state penetrates the contact surface)",
                fix: "use the Dynamic Relaxation solver for contact problems",
            });
        }
        Ok(Solution {
            displacements: u,
            report: Report {
                solver: self.name(),
                steps: iterations,
                err: last_err,
                tolerance: tol,
                rho: 0.0,
                omega_min: 0.0,
                contact: report,
                force_evaluations,
                linear_iterations: 0,
                breakdown: Default::default(),
                elapsed: start.elapsed(),
            },
        })
    }
}
