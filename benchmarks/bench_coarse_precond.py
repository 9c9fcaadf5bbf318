"""Does a coarse (low-l) correction speed up the tension CG? Dense operator at one frame, small meshes only.

Run by hand on a finished inextensible trajectory:
    python benchmarks/bench_coarse_precond.py TRAJECTORY.nc [--time 0.26] [--l-coarse 2 4 6 8 12]

At the frame nearest ``--time`` the operator A = dt D M D^T + W / Lambda is built column by column (one Stokes
solve per triangle) and the frame's right-hand side dt D (M F + u_inf) + (A - A^0) is solved by PCG to the
scheme's tolerance (rms strain of the residual 1e-5), from zero ("cold") and from the stored tension with 1%
noise ("warm"). Preconditioners: the compliance W / Lambda, the local one (tension.LocalPreconditioner), and
each plus an additive coarse correction Z (Z^T A Z)^{-1} Z^T with Z the real Y_lm, l <= l_c, at the triangle
centroids (the exact operator on the smooth patterns: a two-level method). Prints the iterations.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import sys

import numpy as np

from vesicle_core.geometry import surface as Sf
from vesicle_core.geometry import ylm as Yl
from vesicle_core.model.flow import background_velocity
from vesicle_core.solver.tension import LocalPreconditioner, TensionSolver, face_D

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_tension_sources import load_case  # noqa: E402


def real_ylm_basis(points, l_c):
    """Orthonormal columns spanning the real Y_lm, l <= l_c, at ``points`` (relative to the centre)."""
    r = np.linalg.norm(points, axis=1)
    Y = Yl.ylm(l_c, np.arccos(np.clip(points[:, 2] / r, -1, 1)), np.arctan2(points[:, 1], points[:, 0]))
    cols = [Y[l, l_c + m].real for l in range(l_c + 1) for m in range(l + 1)]
    cols += [Y[l, l_c + m].imag for l in range(l_c + 1) for m in range(1, l + 1)]
    return np.linalg.qr(np.array(cols).T)[0]


def pcg(A, b, W, prec, x0, tol=1e-5, maxit=500):
    x, r = x0.copy(), b - A @ x0
    res = lambda r: np.sqrt(np.mean((r / W) ** 2))  # noqa: E731
    if res(r) <= tol:
        return 0
    z = prec(r)
    p, rz = z.copy(), r @ z
    for it in range(1, maxit + 1):
        Ap = A @ p
        alpha = rz / (p @ Ap)
        x += alpha * p
        r -= alpha * Ap
        if res(r) <= tol:
            return it
        z = prec(r)
        rz, rz_old = r @ z, rz
        p = z + rz / rz_old * p
    return maxit


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trajectory")
    ap.add_argument("--time", type=float, default=0.26)
    ap.add_argument("--l-coarse", type=int, nargs="+", default=[2, 4, 6, 8, 12])
    a = ap.parse_args()
    ds, faces, X, cfg, sol, mob = load_case(a.trajectory)
    topo, W, Lam = sol.membrane.topo, sol.membrane.ref.face_area, cfg.Lambda_eff
    k = int(np.argmin(np.abs(ds.time.values - a.time)))
    F, geo = sol.forces(X[k])
    local = LocalPreconditioner(mob, topo, W, Lam)  # measures its pair table: before preparing the frame
    mob.prepare(X[k])
    dt = float(ds.dt_tau.values[k])
    ts = TensionSolver(mob, topo, W, Lam)
    n = len(W)
    A = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1.0
        A[:, j] = ts.operator(e, geo, dt)[0]
    A = 0.5 * (A + A.T)
    u = background_velocity(X[k], float(ds.flow_sign.values[k]) * cfg.chi)
    b = dt * face_D(mob.apply(F) + u, geo, topo) + (geo.area - W)
    warm = ds.face_tension.values[k].astype(float) * (1 + 0.01 * np.random.default_rng(0).standard_normal(n))
    base = {"compliance": lambda r: Lam / W * r, "local": lambda r: local(r, geo, dt)}
    print(f"{a.trajectory}: gamma_dot t = {ds.time.values[k]:.2f}, {n} triangles; CG iterations cold / warm")
    for name, pre in base.items():
        print(f"{name:>26}: {pcg(A, b, W, pre, np.zeros(n)):4d} {pcg(A, b, W, pre, warm):4d}")
    centroids = X[k][faces].mean(axis=1) - Sf.volume_centroid(X[k], faces)
    for l_c in a.l_coarse:
        Z = real_ylm_basis(centroids, l_c)
        Ac_inv = np.linalg.inv(Z.T @ A @ Z)
        for name, pre in base.items():
            two = lambda r, pre=pre, Z=Z, Ci=Ac_inv: pre(r) + Z @ (Ci @ (Z.T @ r))  # noqa: E731
            print(f"{name + ' + coarse l <= ' + str(l_c):>26}: {pcg(A, b, W, two, np.zeros(n)):4d} "
                  f"{pcg(A, b, W, two, warm):4d}")


if __name__ == "__main__":
    main()
