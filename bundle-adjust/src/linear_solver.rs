//! The linear solver of one Levenberg-Marquardt step: Schur elimination, a reduced-system
//! solve (dense, sparse or iterative) and back substitution.

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

/// Everything a step solve needs, built once per solve.
pub(crate) struct LinearSolver {
    kind: LinearSolverType,
    layout: ReducedLayout,
    schur: SchurComplement,
    reduced: Reduced,
    delta_f: Vec<f64>,
    cg: CgOptions,
}

impl LinearSolver {
    pub(crate) fn new(program: &Program, options: &SolverOptions, threads: usize) -> Result<Self> {
        let kind = options.linear_solver.resolve(program.n_f);
        let target = match kind {
            LinearSolverType::SparseSchur => TargetKind::Blocks,
            LinearSolverType::IterativeSchur => TargetKind::Implicit,
            _ => TargetKind::Dense,
        };
        let layout = ReducedLayout::new(program, target);
        let reduced = match target {
            TargetKind::Dense => Reduced::Dense(DenseSolver::new(program.n_f)),
            TargetKind::Blocks => Reduced::Sparse(Box::new(SparseSolver::new(program, &layout)?)),
            TargetKind::Implicit => Reduced::Iterative(SchurJacobi::new()),
        };
        let schur = SchurComplement::new(program, &layout, threads);
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
        })
    }

    /// The solver in use.
    pub(crate) fn kind(&self) -> LinearSolverType {
        self.kind
    }

    /// Solves (JᵀJ + diag(`diag`)) δ = −`gradient` for the scaled Jacobian `jac`, writing δ
    /// (the whole tangent vector) into `delta`. Returns the number of linear iterations, or
    /// `None` when the system is singular or indefinite.
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
    ) -> Option<usize> {
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
        let iterations = match &mut self.reduced {
            Reduced::Dense(d) => {
                let rhs = self.schur.rhs().to_vec();
                d.solve(self.schur.target_mut(), &rhs, &mut self.delta_f)
                    .then_some(1)
            }
            Reduced::Sparse(s) => s
                .solve(self.schur.target(), self.schur.rhs(), &mut self.delta_f)
                .then_some(1),
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
                    result.ok.then_some(result.iterations)
                } else {
                    None
                }
            }
        };
        let t2 = Instant::now();
        times.reduced_solve += (t2 - t1).as_secs_f64();
        let iterations = iterations?;
        delta[n_e..].copy_from_slice(&self.delta_f);
        self.schur.back_substitute(program, delta, exec);
        times.back_substitution += t2.elapsed().as_secs_f64();
        delta.iter().all(|v| v.is_finite()).then_some(iterations)
    }
}
