//! Krylov methods for square systems `A·x = b`: PCG, PBiCG and BiCGSTAB, each preconditioned.
//!
//! All three follow the templates of Barrett et al., *Templates for the Solution of Linear
//! Systems* (SIAM 1994), §2.3.1 (CG), §2.3.5 (BiCG), §2.3.8 (BiCGSTAB).
//!
//! Convergence is tested on the recurrence's residual; when it meets the tolerance the true
//! residual `b − A·x` is recomputed, and if rounding has made the two drift apart the method
//! restarts from the current `x`. BiCG and BiCGSTAB also restart (shadow residual ← `r`) when
//! the shadow residual becomes orthogonal to the residual. At most [`MAX_RESTARTS`] restarts in
//! all; then the solve stops with [`StopReason::Breakdown`] (`"residual gap"` or the vanished
//! product).
//!
//! Singular systems: on a consistent positive semi-definite system (the fit's normal equations
//! with untouched nodes), CG/BiCG iterates from `x₀ = 0` stay in the range of `M⁻¹A` and
//! converge. An inconsistent system cannot reach the tolerance: the solve stops at the
//! iteration limit or at a breakdown, with `converged == false`.

use std::time::Instant;

use crate::error::{SolverError, check_finite, check_len};
use crate::operator::LinearOperator;
use crate::precond::{Preconditioner, build_preconditioner};
use crate::report::{Method, Solution, SolveParams, SolveReport, StopReason};
use crate::vecops::{axpy, cg_update, dot, norm2, xpby};

/// How many times a method may restart after the recomputed residual failed the tolerance that
/// the recurrence's residual met.
pub const MAX_RESTARTS: usize = 3;

/// A scalar that the recurrences divide by counts as vanished below
/// `BREAKDOWN_EPS · ‖u‖·‖v‖` (for a product `uᵀv`).
const BREAKDOWN_EPS: f64 = f64::EPSILON * f64::EPSILON;

/// Validated start of a square solve.
pub(crate) struct Start {
    pub x: Vec<f64>,
    pub bnorm: f64,
}

pub(crate) fn check_params(params: &SolveParams) -> Result<(), SolverError> {
    if !(params.tolerance > 0.0 && params.tolerance.is_finite()) {
        return Err(SolverError::InvalidParameter {
            name: "tolerance",
            value: format!("{}", params.tolerance),
            reason: "must be positive and finite",
        });
    }
    Ok(())
}

/// Checks sizes and values; returns `x₀` and `‖b‖`.
pub(crate) fn start<Op: LinearOperator + ?Sized>(
    method: Method,
    a: &Op,
    b: &[f64],
    params: &SolveParams,
    square: bool,
) -> Result<Start, SolverError> {
    check_params(params)?;
    if square && a.nrows() != a.ncols() {
        return Err(SolverError::NotSquare {
            method: method.name(),
            nrows: a.nrows(),
            ncols: a.ncols(),
        });
    }
    check_len("right-hand side", a.nrows(), b.len())?;
    check_finite("right-hand side", b)?;
    let x = match &params.initial_guess {
        Some(x0) => {
            check_len("initial guess", a.ncols(), x0.len())?;
            check_finite("initial guess", x0)?;
            x0.clone()
        }
        None => vec![0.0; a.ncols()],
    };
    a.check_finite()?;
    Ok(Start { x, bnorm: norm2(b) })
}

/// `r ← b − A·x`; returns `‖r‖`.
pub(crate) fn residual<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    x: &[f64],
    r: &mut [f64],
) -> f64 {
    a.apply(x, r);
    r.iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri);
    norm2(r)
}

/// Bookkeeping shared by the three methods.
struct Run<'a, Op: ?Sized> {
    a: &'a Op,
    b: &'a [f64],
    method: Method,
    precond: &'static str,
    t0: Instant,
    bnorm: f64,
    tol: f64,
    history: Vec<f64>,
    applications: usize,
    restarts: usize,
}

/// What the convergence test decided.
enum Check {
    /// Keep iterating.
    Go,
    /// Confirmed: stop with `Tolerance`.
    Done,
    /// The true residual (now in `r`) failed: reinitialise the directions.
    Restart,
    /// Too many restarts.
    Gap,
}

impl<Op: LinearOperator + ?Sized> Run<'_, Op> {
    fn rel(&self, rnorm: f64) -> f64 {
        rnorm / self.bnorm
    }
    /// Records `‖r‖` and, when it meets the tolerance, recomputes the true residual into `r`.
    fn check(&mut self, x: &[f64], r: &mut [f64], rnorm: f64) -> Check {
        let rel = self.rel(rnorm);
        self.history.push(rel);
        if rel > self.tol {
            return Check::Go;
        }
        let true_norm = residual(self.a, self.b, x, r);
        self.applications += 1;
        if self.rel(true_norm) <= self.tol {
            Check::Done
        } else if self.restarts < MAX_RESTARTS {
            self.restarts += 1;
            Check::Restart
        } else {
            Check::Gap
        }
    }
    fn finish(self, x: Vec<f64>, iterations: usize, stop_reason: StopReason) -> Solution {
        let mut r = vec![0.0; self.b.len()];
        let rel = if self.bnorm > 0.0 {
            residual(self.a, self.b, &x, &mut r) / self.bnorm
        } else {
            0.0
        };
        let converged = stop_reason == StopReason::Tolerance && rel <= self.tol;
        Solution {
            x,
            report: SolveReport {
                method: self.method,
                preconditioner: self.precond,
                iterations,
                operator_applications: self.applications,
                residual_history: self.history,
                relative_residual: rel,
                normal_residual: None,
                time_s: self.t0.elapsed().as_secs_f64(),
                converged,
                stop_reason,
            },
        }
    }
}

fn breakdown(quantity: &'static str, value: f64, iteration: usize) -> StopReason {
    StopReason::Breakdown {
        quantity,
        value,
        iteration,
    }
}

fn gap(iteration: usize, rel: f64) -> StopReason {
    breakdown("residual gap", rel, iteration)
}

/// Strictly positive and finite (false for NaN).
fn positive(v: f64) -> bool {
    v > 0.0 && v.is_finite()
}

/// Vanishes relative to the norms of its factors (or is not finite).
fn vanishes(value: f64, u: f64, v: f64) -> bool {
    !value.is_finite() || value.abs() <= BREAKDOWN_EPS * u * v
}

/// Sets up a run; returns `None` in the run when `b = 0` (solution `x = 0`).
fn begin<'a, Op: LinearOperator + ?Sized>(
    method: Method,
    a: &'a Op,
    m: &dyn Preconditioner,
    b: &'a [f64],
    params: &SolveParams,
    t0: Instant,
) -> Result<(Run<'a, Op>, Vec<f64>), SolverError> {
    let s = start(method, a, b, params, true)?;
    Ok((
        Run {
            a,
            b,
            method,
            precond: m.name(),
            t0,
            bnorm: s.bnorm,
            tol: params.tolerance,
            history: Vec::new(),
            applications: 0,
            restarts: 0,
        },
        s.x,
    ))
}

/// How a Krylov run stands before its first iteration.
enum Begun<'a, Op: ?Sized> {
    /// Solved already: `b = 0` (so `x = 0`) or the initial guess meets the tolerance.
    Done(Solution),
    /// Iterate from `x` with residual `r = b − A·x` (its norm is in the history).
    Iterate {
        run: Run<'a, Op>,
        x: Vec<f64>,
        r: Vec<f64>,
    },
}

/// [`begin`], then the checks every Krylov method makes before its first iteration: a zero
/// right-hand side, and an initial guess that already meets the tolerance. Cost: one product.
fn begin_iteration<'a, Op: LinearOperator + ?Sized>(
    method: Method,
    a: &'a Op,
    m: &dyn Preconditioner,
    b: &'a [f64],
    params: &SolveParams,
    t0: Instant,
) -> Result<Begun<'a, Op>, SolverError> {
    let (mut run, x) = begin(method, a, m, b, params, t0)?;
    let n = b.len();
    if run.bnorm == 0.0 {
        return Ok(Begun::Done(run.finish(
            vec![0.0; n],
            0,
            StopReason::Tolerance,
        )));
    }
    let mut r = vec![0.0; n];
    let rn = residual(a, b, &x, &mut r);
    run.applications += 1;
    run.history.push(run.rel(rn));
    if run.rel(rn) <= run.tol {
        return Ok(Begun::Done(run.finish(x, 0, StopReason::Tolerance)));
    }
    Ok(Begun::Iterate { run, x, r })
}

/// Preconditioned conjugate gradient for symmetric positive (semi-)definite `A`, with the
/// preconditioner given by `params.preconditioner`. Cost per iteration: one product with `A`,
/// one preconditioner application, `10n` flops.
pub fn pcg<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    let t0 = Instant::now();
    let m = build_preconditioner(a, params.preconditioner)?;
    pcg_impl(a, &*m, b, params, t0)
}

/// [`pcg`] with a preconditioner supplied by the caller (`params.preconditioner` is ignored).
pub fn pcg_with<Op: LinearOperator + ?Sized>(
    a: &Op,
    m: &dyn Preconditioner,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    pcg_impl(a, m, b, params, Instant::now())
}

fn pcg_impl<Op: LinearOperator + ?Sized>(
    a: &Op,
    m: &dyn Preconditioner,
    b: &[f64],
    params: &SolveParams,
    t0: Instant,
) -> Result<Solution, SolverError> {
    let (mut run, mut x, mut r) = match begin_iteration(Method::Pcg, a, m, b, params, t0)? {
        Begun::Done(solution) => return Ok(solution),
        Begun::Iterate { run, x, r } => (run, x, r),
    };
    let n = b.len();
    let (mut z, mut q) = (vec![0.0; n], vec![0.0; n]);
    let mut rho = m.apply_dot(&r, &mut z);
    let mut p = z.clone();
    for it in 1..=params.max_iterations {
        if !positive(rho) {
            return Ok(run.finish(x, it - 1, breakdown("rᵀM⁻¹r", rho, it)));
        }
        a.apply(&p, &mut q);
        run.applications += 1;
        let pq = dot(&p, &q);
        if !positive(pq) {
            return Ok(run.finish(x, it - 1, breakdown("pᵀAp", pq, it)));
        }
        let alpha = rho / pq;
        // x ← x + α·p, r ← r − α·q, ‖r‖ (one pass; the same bits as three).
        let rn = cg_update(alpha, &p, &q, &mut x, &mut r);
        match run.check(&x, &mut r, rn) {
            Check::Go => {
                let rho_new = m.apply_dot(&r, &mut z);
                xpby(&z, rho_new / rho, &mut p);
                rho = rho_new;
            }
            Check::Done => return Ok(run.finish(x, it, StopReason::Tolerance)),
            Check::Restart => {
                rho = m.apply_dot(&r, &mut z);
                p.copy_from_slice(&z);
            }
            Check::Gap => {
                let rel = run.rel(norm2(&r));
                return Ok(run.finish(x, it, gap(it, rel)));
            }
        }
    }
    let it = params.max_iterations;
    Ok(run.finish(x, it, StopReason::MaxIterations))
}

/// Preconditioned biconjugate gradient (PBiCG), the method of Baboud's report, for general square
/// `A`. On a symmetric `A` with a symmetric preconditioner it produces CG's iterates at twice
/// the cost. Cost per iteration: one product with `A`, one with `Aᵀ`, two preconditioner
/// applications, `16n` flops.
pub fn pbicg<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    let t0 = Instant::now();
    let m = build_preconditioner(a, params.preconditioner)?;
    // With entries available, store Aᵀ once (one O(nnz) transpose) so that every Aᵀ·p̃ is a
    // parallel row product rather than a serial scatter.
    match a.to_csr() {
        Some(csr) => {
            let op = ExplicitTranspose {
                a,
                at: csr.transpose_view().to_csr(),
            };
            pbicg_impl(&op, &*m, b, params, t0)
        }
        None => pbicg_impl(a, &*m, b, params, t0),
    }
}

/// `A` together with a stored CSR copy of `Aᵀ`, used for `Aᵀ·x`.
struct ExplicitTranspose<'a, Op: ?Sized> {
    a: &'a Op,
    at: sprs::CsMat<f64>,
}

impl<Op: LinearOperator + ?Sized> LinearOperator for ExplicitTranspose<'_, Op> {
    fn nrows(&self) -> usize {
        self.a.nrows()
    }
    fn ncols(&self) -> usize {
        self.a.ncols()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.a.apply(x, y);
    }
    fn apply_transpose(&self, x: &[f64], y: &mut [f64]) {
        self.at.apply(x, y);
    }
    fn to_csr(&self) -> Option<sprs::CsMat<f64>> {
        self.a.to_csr()
    }
    fn diagonal(&self) -> Option<Vec<f64>> {
        self.a.diagonal()
    }
    fn column_norms(&self) -> Option<Vec<f64>> {
        self.a.column_norms()
    }
    fn check_finite(&self) -> Result<(), SolverError> {
        self.a.check_finite()
    }
}

/// [`pbicg`] with a preconditioner supplied by the caller (`params.preconditioner` is ignored).
pub fn pbicg_with<Op: LinearOperator + ?Sized>(
    a: &Op,
    m: &dyn Preconditioner,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    pbicg_impl(a, m, b, params, Instant::now())
}

fn pbicg_impl<Op: LinearOperator + ?Sized>(
    a: &Op,
    m: &dyn Preconditioner,
    b: &[f64],
    params: &SolveParams,
    t0: Instant,
) -> Result<Solution, SolverError> {
    let (mut run, mut x, mut r) = match begin_iteration(Method::Pbicg, a, m, b, params, t0)? {
        Begun::Done(solution) => return Ok(solution),
        Begun::Iterate { run, x, r } => (run, x, r),
    };
    let n = b.len();
    // Shadow residual r̃ = r (the usual choice).
    let mut rt = r.clone();
    let (mut z, mut zt) = (vec![0.0; n], vec![0.0; n]);
    let (mut p, mut pt) = (vec![0.0; n], vec![0.0; n]);
    let (mut q, mut qt) = (vec![0.0; n], vec![0.0; n]);
    let mut rho_prev = 1.0;
    let mut fresh = true;
    for it in 1..=params.max_iterations {
        m.apply(&r, &mut z);
        m.apply_transpose(&rt, &mut zt);
        let mut rho = dot(&z, &rt);
        if vanishes(rho, norm2(&z), norm2(&rt)) {
            // The shadow residual became orthogonal to M⁻¹r: restart the shadow from r.
            if run.restarts >= MAX_RESTARTS {
                return Ok(run.finish(x, it - 1, breakdown("r̃ᵀM⁻¹r", rho, it)));
            }
            run.restarts += 1;
            rt.copy_from_slice(&r);
            m.apply_transpose(&rt, &mut zt);
            fresh = true;
            rho = dot(&z, &rt);
            if vanishes(rho, norm2(&z), norm2(&rt)) {
                return Ok(run.finish(x, it - 1, breakdown("r̃ᵀM⁻¹r", rho, it)));
            }
        }
        if fresh {
            p.copy_from_slice(&z);
            pt.copy_from_slice(&zt);
            fresh = false;
        } else {
            let beta = rho / rho_prev;
            xpby(&z, beta, &mut p);
            xpby(&zt, beta, &mut pt);
        }
        a.apply(&p, &mut q);
        a.apply_transpose(&pt, &mut qt);
        run.applications += 2;
        let sigma = dot(&pt, &q);
        if vanishes(sigma, norm2(&pt), norm2(&q)) {
            return Ok(run.finish(x, it - 1, breakdown("p̃ᵀAp", sigma, it)));
        }
        let alpha = rho / sigma;
        axpy(alpha, &p, &mut x);
        axpy(-alpha, &q, &mut r);
        axpy(-alpha, &qt, &mut rt);
        rho_prev = rho;
        let rn = norm2(&r);
        match run.check(&x, &mut r, rn) {
            Check::Go => {}
            Check::Done => return Ok(run.finish(x, it, StopReason::Tolerance)),
            Check::Restart => {
                rt.copy_from_slice(&r);
                fresh = true;
            }
            Check::Gap => {
                let rel = run.rel(norm2(&r));
                return Ok(run.finish(x, it, gap(it, rel)));
            }
        }
    }
    let it = params.max_iterations;
    Ok(run.finish(x, it, StopReason::MaxIterations))
}

/// Preconditioned BiCGSTAB (right preconditioning) for general square `A`; needs no `Aᵀ`.
/// Cost per iteration: two products with `A`, two preconditioner applications, `20n` flops.
pub fn bicgstab<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    let t0 = Instant::now();
    let m = build_preconditioner(a, params.preconditioner)?;
    bicgstab_impl(a, &*m, b, params, t0)
}

/// [`bicgstab`] with a preconditioner supplied by the caller (`params.preconditioner` is
/// ignored).
pub fn bicgstab_with<Op: LinearOperator + ?Sized>(
    a: &Op,
    m: &dyn Preconditioner,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    bicgstab_impl(a, m, b, params, Instant::now())
}

fn bicgstab_impl<Op: LinearOperator + ?Sized>(
    a: &Op,
    m: &dyn Preconditioner,
    b: &[f64],
    params: &SolveParams,
    t0: Instant,
) -> Result<Solution, SolverError> {
    let (mut run, mut x, mut r) = match begin_iteration(Method::Bicgstab, a, m, b, params, t0)? {
        Begun::Done(solution) => return Ok(solution),
        Begun::Iterate { run, x, r } => (run, x, r),
    };
    let n = b.len();
    let mut rhat = r.clone();
    let (mut p, mut v) = (vec![0.0; n], vec![0.0; n]);
    let (mut phat, mut shat, mut t) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut rho_prev, mut alpha, mut omega) = (1.0, 1.0, 1.0);
    let mut fresh = true;
    for it in 1..=params.max_iterations {
        let mut rho = dot(&rhat, &r);
        if vanishes(rho, norm2(&rhat), norm2(&r)) {
            // The shadow residual became orthogonal to r: restart the shadow from r.
            if run.restarts >= MAX_RESTARTS {
                return Ok(run.finish(x, it - 1, breakdown("r̂ᵀr", rho, it)));
            }
            run.restarts += 1;
            rhat.copy_from_slice(&r);
            fresh = true;
            rho = dot(&rhat, &r);
        }
        if fresh {
            p.copy_from_slice(&r);
            fresh = false;
        } else {
            // p ← r + β (p − ω v)
            let beta = (rho / rho_prev) * (alpha / omega);
            p.iter_mut()
                .zip(r.iter().zip(&v))
                .for_each(|(pi, (ri, vi))| *pi = ri + beta * (*pi - omega * vi));
        }
        m.apply(&p, &mut phat);
        a.apply(&phat, &mut v);
        run.applications += 1;
        let rv = dot(&rhat, &v);
        if vanishes(rv, norm2(&rhat), norm2(&v)) {
            return Ok(run.finish(x, it - 1, breakdown("r̂ᵀAp", rv, it)));
        }
        alpha = rho / rv;
        // s = r − α v, kept in r.
        axpy(-alpha, &v, &mut r);
        let snorm = norm2(&r);
        if run.rel(snorm) <= run.tol {
            axpy(alpha, &phat, &mut x);
            match run.check(&x, &mut r, snorm) {
                Check::Go | Check::Done => return Ok(run.finish(x, it, StopReason::Tolerance)),
                Check::Restart => {
                    rhat.copy_from_slice(&r);
                    fresh = true;
                    rho_prev = 1.0;
                    continue;
                }
                Check::Gap => {
                    let rel = run.rel(norm2(&r));
                    return Ok(run.finish(x, it, gap(it, rel)));
                }
            }
        }
        m.apply(&r, &mut shat);
        a.apply(&shat, &mut t);
        run.applications += 1;
        let tt = dot(&t, &t);
        if !positive(tt) {
            axpy(alpha, &phat, &mut x);
            return Ok(run.finish(x, it, breakdown("tᵀt", tt, it)));
        }
        omega = dot(&t, &r) / tt;
        axpy(alpha, &phat, &mut x);
        axpy(omega, &shat, &mut x);
        axpy(-omega, &t, &mut r);
        rho_prev = rho;
        let rn = norm2(&r);
        match run.check(&x, &mut r, rn) {
            Check::Go => {}
            Check::Done => return Ok(run.finish(x, it, StopReason::Tolerance)),
            Check::Restart => {
                rhat.copy_from_slice(&r);
                fresh = true;
                continue;
            }
            Check::Gap => {
                let rel = run.rel(norm2(&r));
                return Ok(run.finish(x, it, gap(it, rel)));
            }
        }
        if vanishes(omega, 1.0, 1.0) {
            return Ok(run.finish(x, it, breakdown("ω", omega, it)));
        }
    }
    let it = params.max_iterations;
    Ok(run.finish(x, it, StopReason::MaxIterations))
}
