"""Brownian motion of a whole vesicle in the periodic box: its centroid's diffusion against the grid's own
translational mobility and against Hasimoto.

    python benchmarks/vesicle_diffusion.py TRAJECTORY.nc [TRAJECTORY.nc ...] [--lags 0.01 0.05 0.2] > numbers.md

Each trajectory is a noisy run without flow (chi = 0, kT > 0; docs/history/thermal.md section 7). Measured: D =
MSD(lag) /
(6 lag) of the volume centroid (overlapping windows), error bar from 8 time blocks, pooled over the files.

Predicted, from the run's own discretisation (the first file's first frame, N, L, kernel and coupling):

* D_M = kT U / F: a total force F spread over the vertices in proportion to their areas (the uniform traction of
  a translating rigid sphere, which is also the translation of an inextensible vesicle) moves the vertices with a
  mean velocity U through the IBM mobility (steady Stokes, periodic box), so this includes the box exactly;
* R_h: the radius for which Hasimoto's D = kT / (6 pi mu R_h) [1 - 2.837297 x + (4 pi / 3) x^3 - 27.4 x^6],
  x = R_h / L, equals D_M (the vesicle's hydrodynamic radius on this grid; R = 1 is the volume radius);
* D_H(R = 1): Hasimoto with R_h = R, for reference;
* D_N = kT e^T N e, e = dc/dX the volume centroid's gradient (central differences) and N the run's constrained
  mobility (its tension space and solve, fluctuations.ConstrainedMobility, cg_tol 1e-10): the short-time diffusion the
  integrator gives the centroid of this shape. It differs from D_M because the membrane is not rigid and the
  centroid weights are not the uniform traction (0.973 D_M on the 642-vertex sphere at N = 32;
  ``--no-constrained`` skips it, 3 constrained solves and 6 V centroid evaluations).

Lags are in tau (rounded to whole frames of each file); the pooled row averages the files at the same lag.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np
import xarray as xr
from scipy.optimize import brentq

from vesicle_core.geometry.surface import triangle_areas, volume_centroid
from vesicle_core.solver.backend import get_backend
from vesicle_core.solver.ibm import Coupler, Grid
from vesicle_core.solver.kernels import sharpening_symbol
from vesicle_core.solver.mobility import IBMMobility
from vesicle_core.solver.stokes import StokesSolver

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from thermal_diffusion import hasimoto_D  # noqa: E402


def vertex_areas(X, f):
    a = triangle_areas(X, f)
    out = np.zeros(len(X))
    for k in range(3):
        np.add.at(out, f[:, k], a / 3)
    return out


def grid_mobility(ds):
    """kT-free translational mobility U/F of the first frame on the run's grid (mean of the three axes)."""
    N, L = int(ds.attrs["N"]), float(ds.attrs["L"])
    f = ds.face_node_connectivity.values
    X = np.stack([ds.node_x.values[0], ds.node_y.values[0], ds.node_z.values[0]], -1)
    X = X - volume_centroid(X, f)
    be = get_backend("numpy")
    g = Grid(N, L)
    kernel = str(ds.attrs.get("kernel", "peskin4"))
    W = sharpening_symbol(N, kernel, float(ds.attrs.get("sharp_floor", 0.01))) \
        if str(ds.attrs.get("coupling", "kernel")) == "sharp" else None
    mob = IBMMobility(Coupler(g, be, kernel=kernel), StokesSolver(g, be, force_filter=W))
    mob.prepare(X)
    w = vertex_areas(X, f)
    w = w / w.sum()
    m = []
    for c in range(3):
        F = np.zeros_like(X)
        F[:, c] = w  # total force 1
        U = mob.apply(F)
        m.append(float((w * U[:, c]).sum()))
    return float(np.mean(m)), float(np.std(m))


def constrained_centroid_mobility(ds):
    """e^T N e per axis (kT-free) at the first frame, with N the constrained mobility of the run's configuration."""
    from dataclasses import replace

    from vesicle_core.model.run_config import RunConfig
    from vesicle_core.solver.integrators import Inextensible
    from vesicle_core.solver.mobility import IBMSolver

    cfg = replace(RunConfig.from_attrs(ds.attrs), cg_tol=1e-10, cg_maxiter=2000, noise_scheme="euler")
    f = ds.face_node_connectivity.values
    X = np.stack([ds.node_x.values[0], ds.node_y.values[0], ds.node_z.values[0]], -1).astype(float)
    solver = IBMSolver(f, X, cfg)
    con = Inextensible(solver, float(cfg.dt) if not isinstance(cfg.dt, str) else 1e-4, X0=X).thermal.constrained
    con.dt = float(ds.attrs.get("dt_tau", 1e-4))
    eps = 1e-6
    E = np.zeros((3,) + X.shape)
    for i in range(X.shape[0]):
        for a in range(3):
            Xp, Xm = X.copy(), X.copy()
            Xp[i, a] += eps
            Xm[i, a] -= eps
            E[:, i, a] = (volume_centroid(Xp, f) - volume_centroid(Xm, f)) / (2 * eps)
    con.prepare(X)
    return [float((np.asarray(con.apply(E[k])) * E[k]).sum()) for k in range(3)]


def centroid_track(ds):
    f = ds.face_node_connectivity.values
    X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
    return ds.t_tau.values, np.array([volume_centroid(x, f) for x in X])


def msd_D(t, c, lag_tau, blocks=8):
    dt = float(np.median(np.diff(t)))
    lag = max(1, int(round(lag_tau / dt)))
    d = ((c[lag:] - c[:-lag]) ** 2).sum(-1) / (6 * lag * dt)
    parts = np.array_split(d, blocks)
    b = np.array([p.mean() for p in parts])
    return float(b.mean()), float(b.std(ddof=1) / np.sqrt(blocks)), lag * dt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("trajectories", nargs="+")
    ap.add_argument("--lags", type=float, nargs="+", default=[0.01, 0.05, 0.2], help="lags in tau")
    ap.add_argument("--no-constrained", action="store_true", help="skip D_N = kT e^T N e")
    a = ap.parse_args()
    first = xr.open_dataset(a.trajectories[0])
    kT, L = float(first.attrs["kT"]), float(first.attrs["L"])
    mob, mob_sd = grid_mobility(first)
    D_M = kT * mob
    R_h = brentq(lambda r: hasimoto_D(kT, r, L) - D_M, 0.2, 3.0)
    print(f"grid mobility (N = {first.attrs['N']}, L = {L:g}, {first.sizes['n_node']} vertices, "
          f"{first.attrs.get('coupling', 'kernel')} coupling): U/F = {mob:.5f} (axes differ by {mob_sd / mob:.1e}); "
          f"D_M = kT U/F = {D_M:.4e}; R_h = {R_h:.4f} R; Hasimoto at R_h = R: {hasimoto_D(kT, 1.0, L):.4e}")
    if not a.no_constrained:
        eNe = constrained_centroid_mobility(first)
        D_N = kT * float(np.mean(eNe))
        print(f"constrained centroid mobility: D_N = kT e^T N e = {D_N:.4e} = {D_N / D_M:.4f} D_M (axes "
              + ", ".join(f"{kT * x / D_M:.3f}" for x in eNe) + ")")
    else:
        D_N = math.nan
    print()
    print("| file | frames | lag [tau] | D (centroid MSD) | D / D_M - 1 | D / D_N - 1 |")
    print("|---|---|---|---|---|---|")
    tracks = [centroid_track(xr.open_dataset(p)) for p in a.trajectories]
    for lag in a.lags:
        est = [msd_D(t[len(t) // 10:], c[len(t) // 10:], lag) for t, c in tracks]
        for p, (D, e, tl), (t, _) in zip(a.trajectories, est, tracks, strict=True):
            print(f"| {p} | {len(t)} | {tl:.3g} | {D:.4e} +- {e:.1e} | {D / D_M - 1:+.3f} +- {e / D_M:.3f} | "
                  f"{D / D_N - 1:+.3f} +- {e / D_N:.3f} |")
        D = np.mean([x[0] for x in est])
        e = np.sqrt(np.sum([x[1] ** 2 for x in est])) / len(est)
        print(f"| pooled | - | {est[0][2]:.3g} | {D:.4e} +- {e:.1e} | {D / D_M - 1:+.3f} +- {e / D_M:.3f} | "
              f"{D / D_N - 1:+.3f} +- {e / D_N:.3f} |")


if __name__ == "__main__":
    main()
