//! Least-squares methods on a rectangular operator: LSQR and LSMR, `min ‖A·x − b‖₂`.
//!
//! They work on the design matrix itself, so the condition number is that of `A`, not of `AᵀA`
//! as in CG on the normal equations. Both follow the published algorithms (Paige & Saunders,
//! ACM TOMS 8, 1982; Fong & Saunders, SIAM J. Sci. Comput. 33, 2011) as SciPy implements them,
//! without damping and without the condition-number limit.
//!
//! Stopping tests (with `tol = params.tolerance` as both `atol` and `btol`):
//! - `‖r‖ ≤ tol·‖b‖ + tol·‖A‖·‖x‖` → [`StopReason::Tolerance`] (a consistent system solved);
//! - `‖Aᵀr‖ ≤ tol·‖A‖·‖r‖` → [`StopReason::LeastSquares`] (a least-squares solution of an
//!   inconsistent system).
//!
//! Here `‖A‖` is the methods' running Frobenius-norm estimate. Preconditioning:
//! [`PreconditionerKind::Jacobi`] scales the columns by their norms (right preconditioning,
//! `x = D⁻¹y`), which is Jacobi on `AᵀA`; SSOR is not available.

use std::time::Instant;

use crate::error::SolverError;
use crate::krylov::{residual, start};
use crate::operator::{ColumnScaled, LinearOperator};
use crate::precond::PreconditionerKind;
use crate::report::{Method, Solution, SolveParams, SolveReport, StopReason};
use crate::vecops::{axpy, norm2, scale, xpby};

/// What the inner iteration returns.
struct Inner {
    x: Vec<f64>,
    iterations: usize,
    history: Vec<f64>,
    applications: usize,
    stop: StopReason,
}

/// LSQR: `min ‖A·x − b‖₂` for any `m × n` operator. Cost per iteration: one `A·v`, one `Aᵀ·u`,
/// `3m + 5n` flops; memory `m + 3n`.
pub fn lsqr<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    least_squares(Method::Lsqr, a, b, params)
}

/// LSMR: `min ‖A·x − b‖₂` for any `m × n` operator; `‖Aᵀr‖` decreases monotonically, so it
/// can stop earlier than LSQR on the least-squares test. Cost per iteration: one `A·v`, one
/// `Aᵀ·u`, `3m + 8n` flops; memory `m + 4n`.
pub fn lsmr<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    least_squares(Method::Lsmr, a, b, params)
}

fn least_squares<Op: LinearOperator + ?Sized>(
    method: Method,
    a: &Op,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    let t0 = Instant::now();
    let s = start(method, a, b, params, false)?;
    let norms = a.column_norms();
    let (inner, precond) = match params.preconditioner {
        PreconditionerKind::None => (run(method, a, b, s.x, params), "none"),
        PreconditionerKind::Jacobi => {
            let norms = norms
                .clone()
                .ok_or(SolverError::PreconditionerUnavailable {
                    preconditioner: "jacobi",
                    reason: "the operator exposes no column norms",
                })?;
            // Column scaling d_j = ‖a_j‖ (1 for an empty column), x = D⁻¹ y.
            let d: Vec<f64> = norms
                .iter()
                .map(|&c| if c > 0.0 { c } else { 1.0 })
                .collect();
            let op = ColumnScaled {
                inner: a,
                inv_scale: d.iter().map(|v| 1.0 / v).collect(),
            };
            let y0: Vec<f64> = s.x.iter().zip(&d).map(|(x, d)| x * d).collect();
            let mut inner = run(method, &op, b, y0, params);
            inner.x.iter_mut().zip(&d).for_each(|(x, d)| *x /= d);
            (inner, "jacobi")
        }
        PreconditionerKind::Ssor { .. } => {
            return Err(SolverError::PreconditionerUnavailable {
                preconditioner: "ssor",
                reason: "LSQR/LSMR accept only none or jacobi (column scaling)",
            });
        }
    };
    let bnorm = s.bnorm;
    let mut r = vec![0.0; a.nrows()];
    let rnorm = residual(a, b, &inner.x, &mut r);
    let mut atr = vec![0.0; a.ncols()];
    a.apply_transpose(&r, &mut atr);
    let frob = norms.map(|c| norm2(&c));
    let normal_residual = match frob {
        Some(f) if f > 0.0 && rnorm > 0.0 => norm2(&atr) / (f * rnorm),
        _ => 0.0,
    };
    let converged = matches!(inner.stop, StopReason::Tolerance | StopReason::LeastSquares);
    Ok(Solution {
        x: inner.x,
        report: SolveReport {
            method,
            preconditioner: precond,
            iterations: inner.iterations,
            operator_applications: inner.applications + 2,
            residual_history: inner.history,
            relative_residual: if bnorm > 0.0 { rnorm / bnorm } else { 0.0 },
            normal_residual: Some(normal_residual),
            time_s: t0.elapsed().as_secs_f64(),
            converged,
            stop_reason: inner.stop,
        },
    })
}

fn run<Op: LinearOperator + ?Sized>(
    method: Method,
    a: &Op,
    b: &[f64],
    x0: Vec<f64>,
    params: &SolveParams,
) -> Inner {
    match method {
        Method::Lsmr => lsmr_inner(a, b, x0, params),
        _ => lsqr_inner(a, b, x0, params),
    }
}

/// numpy's sign: 0 for 0.
fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Stable Givens rotation: `(c, s, r)` with `[c s; −s c]·[a; b] = [r; 0]`.
fn sym_ortho(a: f64, b: f64) -> (f64, f64, f64) {
    if b == 0.0 {
        (sign(a), 0.0, a.abs())
    } else if a == 0.0 {
        (0.0, sign(b), b.abs())
    } else if b.abs() > a.abs() {
        let tau = a / b;
        let s = sign(b) / (1.0 + tau * tau).sqrt();
        (s * tau, s, b / s)
    } else {
        let tau = b / a;
        let c = sign(a) / (1.0 + tau * tau).sqrt();
        (c, c * tau, a / c)
    }
}

/// Golub–Kahan start: `β u = b − A x₀`, `α v = Aᵀ u`. Returns `(u, v, α, β)`.
fn bidiag_start<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    x: &[f64],
) -> (Vec<f64>, Vec<f64>, f64, f64) {
    let mut u = vec![0.0; a.nrows()];
    let beta = residual(a, b, x, &mut u);
    let mut v = vec![0.0; a.ncols()];
    let mut alpha = 0.0;
    if beta > 0.0 {
        scale(1.0 / beta, &mut u);
        a.apply_transpose(&u, &mut v);
        alpha = norm2(&v);
    }
    if alpha > 0.0 {
        scale(1.0 / alpha, &mut v);
    }
    (u, v, alpha, beta)
}

/// One Golub–Kahan step: `β u ← A v − α u`, `α v ← Aᵀ u − β v`. Returns `(α, β)`.
fn bidiag_step<Op: LinearOperator + ?Sized>(
    a: &Op,
    u: &mut [f64],
    v: &mut [f64],
    av: &mut [f64],
    atu: &mut [f64],
    alpha: f64,
) -> (f64, f64) {
    a.apply(v, av);
    // u ← A v − α u
    xpby(av, -alpha, u);
    let beta = norm2(u);
    let mut alpha_new = 0.0;
    if beta > 0.0 {
        scale(1.0 / beta, u);
        a.apply_transpose(u, atu);
        xpby(atu, -beta, v);
        alpha_new = norm2(v);
        if alpha_new > 0.0 {
            scale(1.0 / alpha_new, v);
        }
    }
    (alpha_new, beta)
}

/// Stops before the first iteration when `x₀` already solves the system (`solved`, or `β = 0`)
/// or is a least-squares solution (`α = 0`: `Aᵀ(b − A x₀) = 0`).
fn trivial(x: Vec<f64>, alpha: f64, beta: f64, solved: bool) -> Option<Inner> {
    if alpha * beta != 0.0 && !solved {
        return None;
    }
    let stop = if beta == 0.0 || solved {
        StopReason::Tolerance
    } else {
        StopReason::LeastSquares
    };
    Some(Inner {
        x,
        iterations: 0,
        history: vec![],
        applications: 2,
        stop,
    })
}

/// The two stopping tests of both methods (see the module docs).
fn stop_test(
    tol: f64,
    bnorm: f64,
    rnorm: f64,
    arnorm: f64,
    anorm: f64,
    xnorm: f64,
) -> Option<StopReason> {
    let test1 = rnorm / bnorm;
    let test2 = if anorm * rnorm > 0.0 {
        arnorm / (anorm * rnorm)
    } else {
        f64::INFINITY
    };
    let t1 = test1 / (1.0 + anorm * xnorm / bnorm);
    let rtol = tol + tol * anorm * xnorm / bnorm;
    if test1 <= rtol || 1.0 + t1 <= 1.0 {
        Some(StopReason::Tolerance)
    } else if test2 <= tol || 1.0 + test2 <= 1.0 {
        Some(StopReason::LeastSquares)
    } else {
        None
    }
}

/// The Golub–Kahan start shared by LSQR and LSMR: `‖b‖`, `β₀u = b − A·x`, `α₀v = Aᵀu`.
struct Bidiag {
    bnorm: f64,
    u: Vec<f64>,
    v: Vec<f64>,
    alpha: f64,
    beta0: f64,
}

/// Starts the bidiagonalisation, or returns the finished result (as `Err`) when `b = 0`
/// (`x = 0`) or the start already solves the problem. Cost: two products.
fn begin_bidiag<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    x: &[f64],
    params: &SolveParams,
) -> Result<Bidiag, Inner> {
    let bnorm = norm2(b);
    if bnorm == 0.0 {
        return Err(Inner {
            x: vec![0.0; a.ncols()],
            iterations: 0,
            history: vec![0.0],
            applications: 0,
            stop: StopReason::Tolerance,
        });
    }
    let (u, v, alpha, beta0) = bidiag_start(a, b, x);
    if let Some(done) = trivial(x.to_vec(), alpha, beta0, beta0 <= params.tolerance * bnorm) {
        return Err(Inner {
            history: vec![beta0 / bnorm],
            ..done
        });
    }
    Ok(Bidiag {
        bnorm,
        u,
        v,
        alpha,
        beta0,
    })
}

fn lsqr_inner<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    mut x: Vec<f64>,
    params: &SolveParams,
) -> Inner {
    let Bidiag {
        bnorm,
        mut u,
        mut v,
        mut alpha,
        beta0,
    } = match begin_bidiag(a, b, &x, params) {
        Ok(start) => start,
        Err(done) => return done,
    };
    let mut applications = 2;
    let mut history = vec![beta0 / bnorm];
    let mut w = v.clone();
    let (mut av, mut atu) = (vec![0.0; a.nrows()], vec![0.0; a.ncols()]);
    let (mut rhobar, mut phibar) = (alpha, beta0);
    let (mut anorm, mut xxnorm, mut z) = (0.0f64, 0.0, 0.0);
    let (mut cs2, mut sn2) = (-1.0, 0.0);
    for itn in 1..=params.max_iterations {
        let (alpha_new, beta) = bidiag_step(a, &mut u, &mut v, &mut av, &mut atu, alpha);
        applications += 2;
        anorm = (anorm * anorm + alpha * alpha + beta * beta).sqrt();
        alpha = alpha_new;
        // Plane rotation eliminating β from the lower bidiagonal.
        let (cs, sn, rho) = sym_ortho(rhobar, beta);
        if rho == 0.0 {
            return Inner {
                x,
                iterations: itn - 1,
                history,
                applications,
                stop: StopReason::Breakdown {
                    quantity: "ρ",
                    value: rho,
                    iteration: itn,
                },
            };
        }
        let theta = sn * alpha;
        rhobar = -cs * alpha;
        let phi = cs * phibar;
        phibar *= sn;
        let tau = sn * phi;
        // x ← x + (φ/ρ) w,  w ← v − (θ/ρ) w.
        axpy(phi / rho, &w, &mut x);
        xpby(&v, -theta / rho, &mut w);
        // ‖x‖ estimate (second rotation).
        let delta = sn2 * rho;
        let gambar = -cs2 * rho;
        let rhs = phi - delta * z;
        let zbar = rhs / gambar;
        let xnorm = (xxnorm + zbar * zbar).sqrt();
        let gamma = gambar.hypot(theta);
        cs2 = gambar / gamma;
        sn2 = theta / gamma;
        z = rhs / gamma;
        xxnorm += z * z;
        let rnorm = phibar.abs();
        let arnorm = alpha * tau.abs();
        history.push(rnorm / bnorm);
        if let Some(stop) = stop_test(params.tolerance, bnorm, rnorm, arnorm, anorm, xnorm) {
            return Inner {
                x,
                iterations: itn,
                history,
                applications,
                stop,
            };
        }
    }
    Inner {
        x,
        iterations: params.max_iterations,
        history,
        applications,
        stop: StopReason::MaxIterations,
    }
}

fn lsmr_inner<Op: LinearOperator + ?Sized>(
    a: &Op,
    b: &[f64],
    mut x: Vec<f64>,
    params: &SolveParams,
) -> Inner {
    let Bidiag {
        bnorm,
        mut u,
        mut v,
        mut alpha,
        beta0,
    } = match begin_bidiag(a, b, &x, params) {
        Ok(start) => start,
        Err(done) => return done,
    };
    let mut applications = 2;
    let mut history = vec![beta0 / bnorm];
    let (mut av, mut atu) = (vec![0.0; a.nrows()], vec![0.0; a.ncols()]);
    let n = a.ncols();
    let mut zetabar = alpha * beta0;
    let mut alphabar = alpha;
    let (mut rho, mut rhobar, mut cbar, mut sbar) = (1.0, 1.0, 1.0, 0.0);
    let mut h = v.clone();
    let mut hbar = vec![0.0; n];
    // Quantities for the ‖r‖ estimate.
    let (mut betadd, mut betad, mut rhodold, mut tautildeold) = (beta0, 0.0, 1.0, 0.0);
    let (mut thetatilde, mut zeta) = (0.0, 0.0);
    let mut norm_a2 = alpha * alpha;
    for itn in 1..=params.max_iterations {
        let (alpha_new, beta) = bidiag_step(a, &mut u, &mut v, &mut av, &mut atu, alpha);
        applications += 2;
        alpha = alpha_new;
        // Rotation P_k (no damping, so Q̂ is the identity: ĉ = 1, ŝ = 0, α̂ = ᾱ).
        let alphahat = alphabar;
        let rhoold = rho;
        let (c, s, rho_new) = sym_ortho(alphahat, beta);
        rho = rho_new;
        let thetanew = s * alpha;
        alphabar = c * alpha;
        // Rotation P̄_k.
        let rhobarold = rhobar;
        let zetaold = zeta;
        let thetabar = sbar * rho;
        let (cb, sb, rb) = sym_ortho(cbar * rho, thetanew);
        cbar = cb;
        sbar = sb;
        rhobar = rb;
        if rho == 0.0 || rhobar == 0.0 {
            return Inner {
                x,
                iterations: itn - 1,
                history,
                applications,
                stop: StopReason::Breakdown {
                    quantity: "ρ̄",
                    value: rhobar,
                    iteration: itn,
                },
            };
        }
        zeta = cbar * zetabar;
        zetabar *= -sbar;
        // h̄ ← h − (θ̄ρ/(ρ_old ρ̄_old)) h̄,  x ← x + (ζ/(ρρ̄)) h̄,  h ← v − (θ/ρ) h.
        xpby(&h, -(thetabar * rho / (rhoold * rhobarold)), &mut hbar);
        axpy(zeta / (rho * rhobar), &hbar, &mut x);
        xpby(&v, -(thetanew / rho), &mut h);
        // ‖r‖ estimate (without damping β́ = β̈ and β̌ = 0).
        let betaacute = betadd;
        let betahat = c * betaacute;
        betadd = -s * betaacute;
        let thetatildeold = thetatilde;
        let (ctildeold, stildeold, rhotildeold) = sym_ortho(rhodold, thetabar);
        thetatilde = stildeold * rhobar;
        rhodold = ctildeold * rhobar;
        betad = -stildeold * betad + ctildeold * betahat;
        tautildeold = (zetaold - thetatildeold * tautildeold) / rhotildeold;
        let taud = (zeta - thetatilde * tautildeold) / rhodold;
        let rnorm = ((betad - taud).powi(2) + betadd * betadd).sqrt();
        // ‖A‖ estimate.
        norm_a2 += beta * beta;
        let anorm = norm_a2.sqrt();
        norm_a2 += alpha * alpha;
        let arnorm = zetabar.abs();
        let xnorm = norm2(&x);
        history.push(rnorm / bnorm);
        if let Some(stop) = stop_test(params.tolerance, bnorm, rnorm, arnorm, anorm, xnorm) {
            return Inner {
                x,
                iterations: itn,
                history,
                applications,
                stop,
            };
        }
    }
    Inner {
        x,
        iterations: params.max_iterations,
        history,
        applications,
        stop: StopReason::MaxIterations,
    }
}
