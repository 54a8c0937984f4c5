"""pyamg side by side with hooke's AMG (docs/solvers.md §2.4) on systems written by
`hooke bench SCENE --export-system DIR`: smoothed aggregation on Newton's clamped Hessian as
3x3 BSR with the 6 rigid-body modes (about the centroid) as near-nullspace, strength
('symmetric', theta 0), Jacobi prolongator smoothing (omega 4/3, pyamg's default), symmetric block
Gauss-Seidel pre- and post-smoothing, max_coarse 1000, splu on the coarsest level, no candidate
improvement; one V-cycle (x0 = 0) per PCG iteration, PCG from x0 = 0 with rhs -grad to the
relative residual given. Times are process CPU seconds (time.process_time) and wall seconds.

    python3 pyamg_systems.py DIR [tolerance=1e-6]

Needs numpy, scipy, pyamg; run with OPENBLAS_NUM_THREADS=1 for one thread.
"""
import sys
import time

import numpy as np
import pyamg
import scipy.io
import scipy.sparse as sp


def rbm(xf):
    nf = xf.shape[0]
    B = np.zeros((nf, 3, 6))
    for c in range(3):
        B[:, c, c] = 1.0
    p = xf - xf.mean(axis=0)
    for r, e in enumerate(np.eye(3)):
        B[:, :, 3 + r] = np.cross(e[None, :], p)
    return B.reshape(3 * nf, 6)


def vcycle(ml):
    levels = ml.levels

    def cycle(level, b):
        A = levels[level].A
        if level == len(levels) - 1:
            return ml.coarse_solver(A, b).reshape(b.shape)
        x = np.zeros_like(b)
        levels[level].presmoother(A, x, b)
        xc = cycle(level + 1, levels[level].R @ (b - A @ x))
        x += levels[level].P @ xc
        levels[level].postsmoother(A, x, b)
        return x

    return lambda b: cycle(0, b)


def pcg(A, b, M, tol, maxiter=1000):
    bn = np.linalg.norm(b)
    x = np.zeros_like(b)
    r = b.copy()
    z = M(r)
    p = z.copy()
    rz = r @ z
    it = 0
    while it < maxiter:
        it += 1
        Ap = A @ p
        alpha = rz / (p @ Ap)
        x += alpha * p
        r -= alpha * Ap
        if np.linalg.norm(r) / bn <= tol:
            break
        z = M(r)
        rz_new = r @ z
        p *= rz_new / rz
        p += z
        rz = rz_new
    return x, it


def main():
    d = sys.argv[1]
    tol = float(sys.argv[2]) if len(sys.argv) > 2 else 1e-6
    H = sp.csr_matrix(scipy.io.mmread(f"{d}/hessian_clamped.mtx"))
    g = np.asarray(scipy.io.mmread(f"{d}/gradient.mtx")).ravel()
    xf = np.asarray(scipy.io.mmread(f"{d}/positions.mtx"))
    b = -g
    kw = dict(strength=("symmetric", {"theta": 0.0}),
              presmoother=("block_gauss_seidel", {"sweep": "symmetric"}),
              postsmoother=("block_gauss_seidel", {"sweep": "symmetric"}),
              max_coarse=1000, coarse_solver="splu", improve_candidates=None)
    c0, w0 = time.process_time(), time.perf_counter()
    ml = pyamg.smoothed_aggregation_solver(H.tobsr(blocksize=(3, 3)), B=rbm(xf), **kw)
    M = vcycle(ml)
    M(np.zeros_like(b))  # builds the coarse LU, counted in the set-up
    c1, w1 = time.process_time(), time.perf_counter()
    x, it = pcg(H, b, M, tol)
    c2, w2 = time.process_time(), time.perf_counter()
    rel = np.linalg.norm(b - H @ x) / np.linalg.norm(b)
    print(f"{d}: pyamg {pyamg.__version__}, n = {H.shape[0]}, levels "
          f"{[lv.A.shape[0] for lv in ml.levels]}, operator complexity {ml.operator_complexity():.3f}; "
          f"CPU s (wall s): set-up {c1 - c0:.3f} ({w1 - w0:.3f}); PCG to {tol:g}: {it} iterations, "
          f"{c2 - c1:.3f} ({w2 - w1:.3f}); set-up + solve {c2 - c0:.3f} ({w2 - w0:.3f}); "
          f"true relative residual {rel:.2e}")


if __name__ == "__main__":
    main()
