//! Preconditioned conjugate gradients on the implicit reduced system (Hestenes and Stiefel
//! 1952), preconditioned with the block diagonal of the Schur complement ("Schur-Jacobi",
//! Agarwal, Snavely, Seitz, Szeliski, "Bundle Adjustment in the Large", ECCV 2010), stopped by
//! Nash and Sofer's truncated-Newton rule (Operations Research Letters 9, 1990): at
//! iteration i stop when i (Q_i − Q_{i−1}) / Q_i < η, with Q the quadratic model. The
//! residual is recomputed from scratch every [`RESIDUAL_RESET_PERIOD`] iterations, as Ceres
//! does, to stop round-off drift.

use crate::kernels::{cholesky, solve_lower, solve_lower_transpose};
use crate::parallel::Executor;
use crate::program::Program;
use crate::reduced::ReducedLayout;
use crate::schur::SchurComplement;

/// Iterations between exact recomputations of the CG residual (Ceres: 10).
const RESIDUAL_RESET_PERIOD: usize = 10;

/// Stopping rule of one conjugate-gradient solve.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CgOptions {
    pub eta: f64,
    pub min_iterations: usize,
    pub max_iterations: usize,
}

/// The factored Schur-Jacobi preconditioner: one Cholesky factor per reduced block.
pub(crate) struct SchurJacobi {
    factors: Vec<f64>,
}

impl SchurJacobi {
    pub(crate) fn new() -> Self {
        Self {
            factors: Vec::new(),
        }
    }

    /// Factors the diagonal blocks of S held by the implicit target. Returns false if one
    /// is not positive definite.
    pub(crate) fn factor(
        &mut self,
        program: &Program,
        layout: &ReducedLayout,
        target: &[f64],
    ) -> bool {
        self.factors.clear();
        for (k, &addr) in layout.diag_addr.iter().enumerate() {
            let m = program.f_size(k);
            let start = self.factors.len();
            self.factors.extend_from_slice(&target[addr..addr + m * m]);
            if !cholesky(&mut self.factors[start..], m) {
                return false;
            }
        }
        true
    }
}

/// A symmetric positive definite approximation M of the reduced matrix, applied as its
/// inverse.
pub(crate) trait Preconditioner {
    /// z = M⁻¹ r.
    fn apply(&mut self, program: &Program, r: &[f64], z: &mut [f64]);
}

impl Preconditioner for SchurJacobi {
    fn apply(&mut self, program: &Program, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
        let mut start = 0;
        for k in 0..program.f_blocks.len() {
            let m = program.f_size(k);
            let off = program.f_offset[k];
            let l = &self.factors[start..start + m * m];
            solve_lower(l, &mut z[off..off + m], m);
            solve_lower_transpose(l, &mut z[off..off + m], m);
            start += m * m;
        }
    }
}

/// Outcome of a CG solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CgResult {
    pub iterations: usize,
    /// False on a numerical breakdown (ρ = rᵀz zero or infinite).
    pub ok: bool,
    /// The stopping rule was met (not the iteration limit or an indefinite direction).
    pub converged: bool,
    /// The quadratic model at the returned x, Q(x) = xᵀSx − 2bᵀx.
    pub q: f64,
}

/// Solves S x = b, S applied implicitly through `schur`, starting from x = 0.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve(
    schur: &mut SchurComplement,
    program: &Program,
    layout: &ReducedLayout,
    preconditioner: &mut dyn Preconditioner,
    diag_f: &[f64],
    b: &[f64],
    x: &mut [f64],
    options: CgOptions,
    exec: &Executor,
) -> CgResult {
    let n = b.len();
    x.fill(0.0);
    let norm_b = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm_b == 0.0 {
        return CgResult {
            iterations: 0,
            ok: true,
            converged: true,
            q: 0.0,
        };
    }
    let mut r = b.to_vec();
    let mut z = vec![0.0; n];
    let mut p = vec![0.0; n];
    let mut q = vec![0.0; n];
    let mut rho = 1.0;
    let dot = |a: &[f64], c: &[f64]| a.iter().zip(c).map(|(u, v)| u * v).sum::<f64>();
    // Q(x) = xᵀSx − 2bᵀx = −xᵀ(b + r); zero at x = 0.
    let mut q0 = 0.0;
    let mut iteration = 1;
    loop {
        preconditioner.apply(program, &r, &mut z);
        let last_rho = rho;
        rho = dot(&r, &z);
        if rho == 0.0 || !rho.is_finite() {
            return CgResult {
                iterations: iteration,
                ok: false,
                converged: false,
                q: q0,
            };
        }
        if iteration == 1 {
            p.copy_from_slice(&z);
        } else {
            let beta = rho / last_rho;
            if beta == 0.0 || !beta.is_finite() {
                return CgResult {
                    iterations: iteration,
                    ok: false,
                    converged: false,
                    q: q0,
                };
            }
            for (pi, zi) in p.iter_mut().zip(&z) {
                *pi = zi + beta * *pi;
            }
        }
        schur.implicit_product(program, layout, diag_f, &p, &mut q, exec);
        let pq = dot(&p, &q);
        if pq <= 0.0 || !pq.is_finite() {
            // Indefinite (round-off): keep the iterate reached so far.
            return CgResult {
                iterations: iteration,
                ok: true,
                converged: false,
                q: q0,
            };
        }
        let alpha = rho / pq;
        for (xi, pi) in x.iter_mut().zip(&p) {
            *xi += alpha * pi;
        }
        if iteration % RESIDUAL_RESET_PERIOD == 0 {
            schur.implicit_product(program, layout, diag_f, x, &mut q, exec);
            for ((ri, bi), qi) in r.iter_mut().zip(b).zip(&q) {
                *ri = bi - qi;
            }
        } else {
            for (ri, qi) in r.iter_mut().zip(&q) {
                *ri -= alpha * qi;
            }
        }
        let q1 = -x
            .iter()
            .zip(b.iter().zip(&r))
            .map(|(xi, (bi, ri))| xi * (bi + ri))
            .sum::<f64>();
        let zeta = iteration as f64 * (q1 - q0) / q1;
        if zeta < options.eta && iteration >= options.min_iterations {
            return CgResult {
                iterations: iteration,
                ok: true,
                converged: true,
                q: q1,
            };
        }
        q0 = q1;
        if iteration >= options.max_iterations {
            return CgResult {
                iterations: iteration,
                ok: true,
                converged: false,
                q: q1,
            };
        }
        iteration += 1;
    }
}
