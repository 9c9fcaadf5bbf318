"""The tension operator of the inextensible scheme: its conditioning and the tension stability limit.

    python benchmarks/bench_tension.py [--N 64] [--n-vertices 642] [--chi 267.8] [--coupling sharp] [--stability-only]

1. Tension stability: the largest eigenvalue |lam| of the linearised membrane velocity under a uniform tension
   sigma (bending + sigma H, power iteration), for sigma = 0, 2000, 8000. |lam| h / sigma is the constant behind
   integrators.TENSION_STABILITY (forward Euler is stable for |lam| dt < 2).
2. Conditioning: the dense operator A = dt D M D^T + W / Lambda (one Stokes solve per triangle: keep the mesh
   small), its condition number with the compliance preconditioner W / Lambda, and the range of the area rate
   per unit tension.
3. Why a local-mobility preconditioner fails: the IBM's own pair mobility (self + pairs closer than r_cut,
   mobility.local_mobility_matrix) has negative eigenvalues once truncated.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse

import numpy as np
import scipy.linalg as sl

from vesicle_core.geometry import mesh as M
from vesicle_core.model.run_config import legacy_config
from vesicle_core.solver.mobility import IBMMobility, IBMSolver
from vesicle_core.solver.step_size import stability_dt
from vesicle_core.solver.tension import TensionSolver


def _with_uniform_tension(forces, sigma):
    """Membrane forces plus the force sigma H of a uniform tension (held fixed while the shape moves)."""

    def f(X):
        F, geo = forces(X)
        return F + sigma * geo.H, geo

    return f


def stability(mesh, N, chi, coupling="kernel"):
    for sigma in (0.0, 2000.0, 8000.0):
        s = IBMSolver(mesh.faces, mesh.vertices, legacy_config(chi=chi, N=N, scheme="inextensible", coupling=coupling))
        s.membrane.forces = _with_uniform_tension(s.membrane.forces, sigma)
        _, lam = stability_dt(s, s.xp.asarray(mesh.vertices), max_iter=60)
        ratio = f"{lam * s.grid.h / sigma:.3f}" if sigma else "-"
        print(f"sigma = {sigma:6.0f}: |lam|max = {lam:.4g} /tau   |lam| h / sigma = {ratio}", flush=True)


def conditioning(mesh, N, chi, Lam, dt):
    s = IBMSolver(mesh.faces, mesh.vertices, legacy_config(chi=chi, N=N, scheme="inextensible"))
    X = mesh.vertices
    _, geo = s.forces(X)
    mob = IBMMobility(s.coupler, s.stokes)
    mob.prepare(X)
    W = geo.area.copy()
    ts = TensionSolver(mob, s.membrane.topo, W, Lam)
    n = len(W)
    A = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1.0
        A[:, j] = ts.operator(e, geo, 1.0)[0]
    print(f"dense operator: asymmetry {np.abs(A - A.T).max() / np.abs(A).max():.1e}", flush=True)
    A = 0.5 * (A + A.T)
    ev = sl.eigh(dt * A + np.diag(W / Lam), np.diag(W / Lam), eigvals_only=True)
    print(f"compliance-preconditioned: eigenvalues [{ev.min():.3g}, {ev.max():.3g}], condition number "
          f"{ev.max() / ev.min():.3g} (dt = {dt:.3g}, Lambda = {Lam:.3g})")
    Wh = np.diag(W**-0.5)
    rho, Q = np.linalg.eigh(Wh @ A @ Wh)
    return rho, Q


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--N", type=int, default=64)
    ap.add_argument("--n-vertices", type=int, default=642)
    ap.add_argument("--chi", type=float, default=267.8)
    ap.add_argument("--coupling", default="kernel", choices=("kernel", "sharp"))
    ap.add_argument("--stability-only", action="store_true", help="part 1 alone")
    a = ap.parse_args()
    mesh = M.make_vesicle("quasiuniform", n_vertices=a.n_vertices, axes=(1.0, 0.8, 1.0))
    stability(mesh, a.N, a.chi, a.coupling)
    if a.stability_only:
        return
    rho, _ = conditioning(mesh, a.N, a.chi, Lam=max(1e6, 5e4 * a.chi), dt=0.01 / a.chi)
    print(f"area rate per unit tension (W^-1/2 D M D^T W^-1/2): max {rho.max():.3g}, median {np.median(rho):.3g}, "
          f"min {rho.min():.3g}")
    local_mobility(mesh, a.N, a.chi)


def local_mobility(mesh, N, chi):
    import scipy.sparse.linalg as spla

    from vesicle_core.solver.mobility import local_mobility_matrix, pair_table

    s = IBMSolver(mesh.faces, mesh.vertices, legacy_config(chi=chi, N=N, scheme="inextensible"))
    table = pair_table(IBMMobility(s.coupler, s.stokes))
    for r_cut in (1.5, 2.0, 3.0):
        Ml = local_mobility_matrix(mesh.vertices, table, r_cut=r_cut * s.grid.h)
        lo = spla.eigsh(Ml, k=1, which="SA")[0][0]
        print(f"local mobility, pairs within {r_cut} h: smallest eigenvalue {lo:.3g} (self-mobility "
              f"{table.self_mobility:.3g}, a_h = {table.hydrodynamic_radius:.3f} h)")


if __name__ == "__main__":
    main()
