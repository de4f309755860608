#!/usr/bin/env python3
"""Solve the trilinear fit's systems with altrep's solvers and with SciPy's, in one run.

Usage: python3 bench/scipy_compare.py [--samples 64x32x128] [--grid 15x8x16] [--repeat 5]
                                      [--altrep PATH] [--keep DIR]

The script makes its own virtualenv (bench/.venv, with numpy and scipy from PyPI) and re-runs
itself inside it. It then runs `altrep fit-bench --export-mm DIR --json FILE` (which times
altrep's solvers, median of --repeat solves, and writes the normal equations and the design
matrix at the default lambda as MatrixMarket files), loads the same files with SciPy, times
scipy.sparse.linalg's cg, bicg, bicgstab, lsqr and lsmr on them with the same preconditioning
and tolerance, and prints, per method, the time ratio altrep/SciPy and both residuals.

Preconditioning matches altrep's: Jacobi (inverse diagonal, 1 on zero-diagonal rows) for
cg/bicg/bicgstab; column scaling by column norms for lsqr/lsmr. SciPy's times include building
the preconditioner, as altrep's do. The residual shown for every method is the normal-equation
residual ||A'd - (A'A + cL) x|| / ||A'd||, the measure altrep's table uses.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

from venvs import ensure_venv

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_altrep(args, out):
    json_path = os.path.join(out, "altrep.json")
    fb = [
        "fit-bench",
        "--grid", args.grid,
        "--samples", args.samples,
        "--lambda", "1e-4",
        "--repeat", str(args.repeat),
        "--tolerance", str(args.tolerance),
        "--json", json_path,
        "--export-mm", out,
    ]
    if args.altrep:
        cmd = [args.altrep] + fb
    else:
        cmd = ["cargo", "run", "--release", "--quiet", "--bin", "altrep", "--"] + fb
    print("$ " + " ".join(cmd), flush=True)
    subprocess.check_call(cmd, cwd=ROOT)
    with open(json_path) as f:
        return json.load(f)


def main():
    ensure_venv(".venv", ["numpy", "scipy"], __file__)
    import numpy as np
    import scipy
    import scipy.io
    import scipy.sparse as sp
    import scipy.sparse.linalg as sla

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", default="64x32x128")
    ap.add_argument("--grid", default="15x8x16")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--tolerance", type=float, default=1e-10)
    ap.add_argument("--altrep", help="path of a built altrep binary (default: cargo run --release)")
    ap.add_argument("--keep", help="keep the MatrixMarket files in this folder")
    args = ap.parse_args()

    out = args.keep or tempfile.mkdtemp(prefix="altrep-scipy-")
    os.makedirs(out, exist_ok=True)
    try:
        report = run_altrep(args, out)
        N = sp.csr_matrix(scipy.io.mmread(os.path.join(out, "normal.mtx")))
        b = np.asarray(scipy.io.mmread(os.path.join(out, "normal_rhs.mtx"))).ravel()
        A = sp.csr_matrix(scipy.io.mmread(os.path.join(out, "design.mtx")))
        d = np.asarray(scipy.io.mmread(os.path.join(out, "design_rhs.mtx"))).ravel()
    finally:
        if not args.keep:
            shutil.rmtree(out, ignore_errors=True)

    tol, maxiter = args.tolerance, 10_000
    bnorm = np.linalg.norm(b)

    def normal_residual(x):
        return np.linalg.norm(b - N @ x) / bnorm

    def jacobi():
        diag = N.diagonal().copy()
        diag[diag == 0] = 1.0
        return sp.diags(1.0 / diag).tocsr()

    def krylov(fn):
        def solve():
            it = [0]
            M = jacobi()
            x, info = fn(N, b, rtol=tol, atol=0.0, maxiter=maxiter, M=M,
                         callback=lambda xk: it.__setitem__(0, it[0] + 1))
            return x, it[0], info == 0
        return solve

    def least_squares(fn, lsqr_like):
        def solve():
            c = np.sqrt(np.asarray(A.multiply(A).sum(axis=0)).ravel())
            c[c == 0] = 1.0
            As = A @ sp.diags(1.0 / c)
            if lsqr_like:
                r = fn(As, d, atol=tol, btol=tol, conlim=0, iter_lim=maxiter)
            else:
                r = fn(As, d, atol=tol, btol=tol, conlim=0, maxiter=maxiter)
            y, istop, itn = r[0], r[1], r[2]
            return y / c, itn, istop in (1, 2, 4, 5)
        return solve

    methods = [
        ("cg", "pcg+jacobi", krylov(sla.cg)),
        ("bicg", "pbicg+jacobi", krylov(sla.bicg)),
        ("bicgstab", "bicgstab+jacobi", krylov(sla.bicgstab)),
        ("lsqr", "lsqr+jacobi", least_squares(sla.lsqr, True)),
        ("lsmr", "lsmr+jacobi", least_squares(sla.lsmr, False)),
    ]
    ours = {s["solver"]: s for s in report["solvers"]}
    print()
    print(f"SciPy {scipy.__version__}, NumPy {np.__version__}; system: {N.shape[0]} unknowns, "
          f"{N.nnz} non-zeros (normal), design {A.shape[0]}x{A.shape[1]} with {A.nnz} non-zeros; "
          f"altrep threads: {report['threads']}, SciPy sparse products: 1 thread")
    print(f"{'method':<10} {'altrep ms':>10} {'scipy ms':>10} {'altrep/scipy':>13} "
          f"{'iters a/s':>11} {'residual altrep':>16} {'residual scipy':>15}")
    rows = []
    for name, ours_name, solve in methods:
        times, res = [], None
        for _ in range(max(1, args.repeat)):
            t0 = time.perf_counter()
            res = solve()
            times.append((time.perf_counter() - t0) * 1e3)
        x, its, ok = res
        ms = float(np.median(times))
        a = ours[ours_name]
        ratio = a["solve_ms"] / ms
        print(f"{name:<10} {a['solve_ms']:>10.3f} {ms:>10.3f} {ratio:>13.3f} "
              f"{a['iterations']:>5}/{its:<5} {a['rel_residual']:>16.3e} "
              f"{normal_residual(x):>15.3e}{'' if ok else '  (scipy: not converged)'}")
        rows.append({"method": name, "altrep_ms": a["solve_ms"], "scipy_ms": ms,
                     "ratio": ratio, "altrep_iterations": a["iterations"],
                     "scipy_iterations": its, "altrep_residual": a["rel_residual"],
                     "scipy_residual": normal_residual(x), "scipy_converged": bool(ok)})
    print(json.dumps({"scipy_compare": rows}))


if __name__ == "__main__":
    main()
