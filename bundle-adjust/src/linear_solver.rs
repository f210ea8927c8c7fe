//! The linear solver of one Levenberg-Marquardt step: Schur elimination, a reduced-system
//! solve (dense, sparse or iterative) and back substitution.
//!
//! With [`SolverOptions::reuse_factorization`] the sparse solver factors the reduced matrix
//! only when it must: a step after the first is solved by conjugate gradients on the exact
//! reduced system S (applied implicitly, as the iterative solver does), preconditioned by
//! the last factor, of S' from an earlier Jacobian or damping. Near a minimum the Jacobian
//! changes little from one step to the next and M⁻¹S is close to the identity, so a few
//! products with S and triangular solves with the old factor replace forming S (the O(k²)
//! block products of every point seen in k images) and factoring it: the "lagged"
//! preconditioner of Newton-Krylov methods (Knoll and Keyes, "Jacobian-free Newton-Krylov
//! methods: a survey of approaches and applications", J. Comput. Phys. 193, 2004). A step
//! whose conjugate gradients do not converge within [`REUSE_MAX_ITERATIONS`] is solved again
//! with a fresh factorization.

use std::time::Instant;

use crate::dense_solver::DenseSolver;
use crate::error::Result;
use crate::options::{LinearSolverType, SolverOptions};
use crate::parallel::Executor;
use crate::pcg::{self, CgOptions, SchurJacobi};
use crate::program::Program;
use crate::reduced::{ReducedLayout, TargetKind};
use crate::schur::SchurComplement;
use crate::sparse_solver::SparseSolver;
use crate::summary::StageTimes;

enum Reduced {
    Dense(DenseSolver),
    Sparse(Box<SparseSolver>),
    Iterative(SchurJacobi),
}

/// Conjugate-gradient iterations a step preconditioned by an earlier factor may take before
/// the reduced matrix is formed and factored afresh.
const REUSE_MAX_ITERATIONS: usize = 20;

/// The truncated-Newton tolerance η of a step preconditioned by an earlier factor: the
/// quadratic model's last relative decrease, times the iteration count, below 1e-3, so that
/// the step's model value is within about 1e-3 of the exact one (a direct solve's), its
/// energy-norm error about 3%. Measured on the full garage (4 x 500 frames, intrinsics
/// free, from the initial trust-region radius 1e4 the rig bundle adjustment then used):
/// final costs 1.5e-5, 1.9e-4 and 4.3e-3 above the solve at 1e-6 for η = 1e-4, 1e-3
/// and 1e-2 (of 3.2e5; the function tolerance stops within 0.32), with 4-7 iterations a step
/// at 1e-3 against 7-13 at 1e-6. The parameters along weakly determined directions follow
/// the exact steps' at 1e-3 (worst extrinsic error 0.00491 against 0.00490 deg); at 1e-2
/// they moved by 8 % of their error (0.00528 deg).
const REUSE_ETA: f64 = 1e-3;

/// Everything a step solve needs, built once per solve.
pub(crate) struct LinearSolver {
    kind: LinearSolverType,
    layout: ReducedLayout,
    schur: SchurComplement,
    reduced: Reduced,
    delta_f: Vec<f64>,
    cg: CgOptions,
    /// The implicit layout of the steps preconditioned by the sparse solver's last factor
    /// ([`SolverOptions::reuse_factorization`]).
    reuse: Option<ReducedLayout>,
    /// Whether the next step may try the last factor.
    reuse_allowed: bool,
}

/// How a step was solved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StepSolve {
    /// Linear iterations (1 for a direct solve).
    pub iterations: usize,
    /// The damped quadratic model at the step, gᵀδ + ½ δᵀ(JᵀJ + D)δ, from the reduced
    /// system: with δe back-substituted exactly it is ½ Q(δf) − ½ |L⁻¹g_e|², where
    /// Q(x) = xᵀSx − 2 bᵀx (= −bᵀδf for a direct solve) and A = LLᵀ the eliminated blocks.
    pub quadratic: f64,
}

impl LinearSolver {
    pub(crate) fn new(program: &Program, options: &SolverOptions, threads: usize) -> Result<Self> {
        let kind = options.linear_solver.resolve(program.n_f);
        let target = match kind {
            LinearSolverType::SparseSchur => TargetKind::Blocks,
            LinearSolverType::IterativeSchur => TargetKind::Implicit,
            _ => TargetKind::Dense,
        };
        let reusing = options.reuse_factorization && target == TargetKind::Blocks;
        let layout = ReducedLayout::new(program, target)?;
        let reuse = if reusing {
            Some(ReducedLayout::new(program, TargetKind::Implicit)?.without_preconditioner())
        } else {
            None
        };
        let reduced = match target {
            TargetKind::Dense => Reduced::Dense(DenseSolver::new(program.n_f)),
            TargetKind::Blocks => Reduced::Sparse(Box::new(SparseSolver::new(program, &layout)?)),
            TargetKind::Implicit => Reduced::Iterative(SchurJacobi::new()),
        };
        let schur = match &reuse {
            Some(implicit) => SchurComplement::with_layouts(program, &[&layout, implicit], threads),
            None => SchurComplement::new(program, &layout, threads),
        };
        Ok(Self {
            kind: if target == TargetKind::Dense {
                LinearSolverType::DenseSchur
            } else {
                kind
            },
            layout,
            schur,
            reduced,
            delta_f: vec![0.0; program.n_f],
            cg: CgOptions {
                eta: options.eta,
                min_iterations: options.min_linear_solver_iterations,
                max_iterations: options.max_linear_solver_iterations,
            },
            reuse,
            reuse_allowed: true,
        })
    }

    /// Whether the next step may be preconditioned by the last factor: the minimizer says
    /// no after a step that changed the Jacobian too much for it (the cost falling by more
    /// than half).
    pub(crate) fn allow_reuse(&mut self, allowed: bool) {
        self.reuse_allowed = allowed;
    }

    /// The solver in use.
    pub(crate) fn kind(&self) -> LinearSolverType {
        self.kind
    }

    /// Solves (JᵀJ + diag(`diag`)) δ = −`gradient` for the scaled Jacobian `jac`, writing δ
    /// (the whole tangent vector) into `delta`. Returns how it was solved, or `None` when
    /// the system is singular or indefinite.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn solve(
        &mut self,
        program: &Program,
        jac: &[f64],
        gradient: &[f64],
        diag: &[f64],
        delta: &mut [f64],
        exec: &Executor,
        times: &mut StageTimes,
    ) -> Option<StepSolve> {
        if let Some(solved) = self.solve_reusing(program, jac, gradient, diag, delta, exec, times) {
            return Some(solved);
        }
        let t0 = Instant::now();
        let ok = self
            .schur
            .eliminate(program, &self.layout, jac, gradient, diag, exec);
        let t1 = Instant::now();
        times.schur_elimination += (t1 - t0).as_secs_f64();
        if !ok {
            return None;
        }
        let n_e = program.n_e;
        let direct_q = |rhs: &[f64], x: &[f64]| -rhs.iter().zip(x).map(|(b, v)| b * v).sum::<f64>();
        let solved = match &mut self.reduced {
            Reduced::Dense(d) => {
                let rhs = self.schur.rhs().to_vec();
                d.solve(self.schur.target_mut(), &rhs, &mut self.delta_f)
                    .then(|| (1, direct_q(&rhs, &self.delta_f)))
            }
            Reduced::Sparse(s) => s
                .solve(self.schur.target(), self.schur.rhs(), &mut self.delta_f)
                .then(|| (1, direct_q(self.schur.rhs(), &self.delta_f))),
            Reduced::Iterative(pre) => {
                if pre.factor(program, &self.layout, self.schur.target()) {
                    let rhs = self.schur.rhs().to_vec();
                    let result = pcg::solve(
                        &mut self.schur,
                        program,
                        &self.layout,
                        pre,
                        &diag[n_e..],
                        &rhs,
                        &mut self.delta_f,
                        self.cg,
                        exec,
                    );
                    result.ok.then_some((result.iterations, result.q))
                } else {
                    None
                }
            }
        };
        let t2 = Instant::now();
        times.reduced_solve += (t2 - t1).as_secs_f64();
        let (iterations, q) = solved?;
        self.finish(program, delta, iterations, q, exec, times, t2)
    }

    /// Back substitution of the reduced step (in `delta_f`) into `delta`.
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &self,
        program: &Program,
        delta: &mut [f64],
        iterations: usize,
        q: f64,
        exec: &Executor,
        times: &mut StageTimes,
        start: Instant,
    ) -> Option<StepSolve> {
        delta[program.n_e..].copy_from_slice(&self.delta_f);
        self.schur.back_substitute(program, delta, exec);
        times.back_substitution += start.elapsed().as_secs_f64();
        delta.iter().all(|v| v.is_finite()).then(|| StepSolve {
            iterations,
            quadratic: 0.5 * (q - self.schur.eliminated_norm2()),
        })
    }

    /// The step by conjugate gradients preconditioned by the sparse solver's last factor,
    /// when reuse is on and a factor is kept; `None` (nothing kept of the attempt) when that
    /// does not converge within [`REUSE_MAX_ITERATIONS`].
    #[allow(clippy::too_many_arguments)]
    fn solve_reusing(
        &mut self,
        program: &Program,
        jac: &[f64],
        gradient: &[f64],
        diag: &[f64],
        delta: &mut [f64],
        exec: &Executor,
        times: &mut StageTimes,
    ) -> Option<StepSolve> {
        let (Some(implicit), Reduced::Sparse(factor)) = (&self.reuse, &mut self.reduced) else {
            return None;
        };
        if !(self.reuse_allowed && factor.factored()) {
            return None;
        }
        let t0 = Instant::now();
        let ok = self
            .schur
            .eliminate(program, implicit, jac, gradient, diag, exec);
        let t1 = Instant::now();
        times.schur_elimination += (t1 - t0).as_secs_f64();
        if !ok {
            return None;
        }
        let n_e = program.n_e;
        let rhs = self.schur.rhs().to_vec();
        let result = pcg::solve(
            &mut self.schur,
            program,
            implicit,
            factor.as_mut(),
            &diag[n_e..],
            &rhs,
            &mut self.delta_f,
            CgOptions {
                eta: REUSE_ETA,
                min_iterations: 1,
                max_iterations: REUSE_MAX_ITERATIONS,
            },
            exec,
        );
        let t2 = Instant::now();
        times.reduced_solve += (t2 - t1).as_secs_f64();
        if !(result.ok && result.converged) {
            return None;
        }
        self.finish(program, delta, result.iterations, result.q, exec, times, t2)
    }
}
