"""The bending stability limit's measurement on the frames of a finished run: power iteration against Arnoldi
(run by hand).

    python benchmarks/bench_step_size.py RUN_DIR [--frames 20,24,60,64,80,84]

RUN_DIR holds a run's run.yaml and trajectory.nc. At each frame, a reference |lam|max: Arnoldi (60 iterations,
rtol 1e-5) on the whole linearised velocity d(M(X) F(X))/dX, by one-sided differences of the velocity on a float64
copy of the run's solver, so that neither the force-only product nor the run's float32 grid is assumed. Then, from
a random start, the power iteration this replaced (30 iterations, rtol 1e-3, two solves per iteration, as `dt:
power` measured before) and step_size.stiffest_mode (as a fresh run's first measurement); and, from the previous
frame's vectors, both as a run's re-measurement does it (power: 20 iterations, rtol 1e-2; Arnoldi: 20 iterations,
rtol 1e-3). Prints |lam|, its error against the reference and the Stokes solves. Pick frames about BENDING_REFRESH
steps apart (the run's dt_tau says how many steps a frame spans) so that the warm start is the run's own.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import dataclasses
import time

import numpy as np
import xarray as xr

from vesicle_core.model.run_config import load_config
from vesicle_core.solver.mobility import IBMSolver
from vesicle_core.solver.step_size import arnoldi, stiffest_mode


def power_iteration(solver, X, v0=None, iters=30, rtol=1e-3, seed=0):
    """The estimate this project used before stiffest_mode: |J v| / |v| with J v a centred difference of the
    velocity (two solves), stopped when it changes by less than rtol -> (|lam|, vector, solves)."""
    xp = solver.xp
    v = xp.asarray(np.random.default_rng(seed).standard_normal(X.shape)) if v0 is None else xp.asarray(v0) + 0.0
    v /= float(xp.linalg.norm(v))
    scale = 1e-7 * float(xp.abs(X).max())
    lam, solves = 0.0, 0
    for _ in range(iters):
        Jv = (solver.membrane_velocity(X + scale * v) - solver.membrane_velocity(X - scale * v)) / (2 * scale)
        solves += 2
        new = float(xp.linalg.norm(Jv))
        v = Jv / new
        done = abs(new - lam) < rtol * new
        lam = new
        if done:
            break
    return lam, v, solves


def _velocity_difference(solver, X):
    """v -> (u(X + eps v) - u(X)) / eps: the whole linearised velocity, mobility change included."""
    u0 = solver.membrane_velocity(X)
    eps = 1e-7 * float(abs(X).max())
    return lambda v: (solver.membrane_velocity(X + eps * v) - u0) / eps


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir")
    ap.add_argument("--frames", default="20,24,60,64,80,84", help="comma-separated frame indices")
    a = ap.parse_args(argv)
    cfg = load_config(os.path.join(a.run_dir, "run.yaml"))
    ds = xr.open_dataset(os.path.join(a.run_dir, "trajectory.nc"))
    faces = ds.face_node_connectivity.values

    def shape(k):
        return np.stack([ds.node_x.values[k], ds.node_y.values[k], ds.node_z.values[k]], -1)

    s = IBMSolver(faces, shape(0), cfg)
    s64 = IBMSolver(faces, shape(0), dataclasses.replace(cfg, dtype="float64"))
    prev = None
    rows = []
    for k in (int(f) for f in a.frames.split(",")):
        X = s.xp.asarray(shape(k))
        t0 = time.perf_counter()
        ref, _, n_ref = arnoldi(_velocity_difference(s64, X), np.random.default_rng(0).standard_normal(X.shape),
                                max_iter=60, rtol=1e-5)
        print(f"frame {k} (gamma_dot t = {float(ds.time[k]):+.2f}): reference |lam| = {ref:.6g} /tau "
              f"({n_ref} solves, {time.perf_counter() - t0:.1f} s)", flush=True)
        lp, vp, n_p = power_iteration(s, X)
        la, va, n_a = stiffest_mode(s, X)
        rows.append(("cold", lp / ref - 1, n_p, la / ref - 1, n_a))
        if prev is not None:
            lp2, _, n_p2 = power_iteration(s, X, v0=prev[0], iters=20, rtol=1e-2)
            la2, _, n_a2 = stiffest_mode(s, X, v0=prev[1], max_iter=20)
            rows.append(("warm", lp2 / ref - 1, n_p2, la2 / ref - 1, n_a2))
        for kind, ep, np_, ea, na in rows[-2 if prev is not None else -1:]:
            print(f"  {kind}: power {ep:+.2%} in {np_} solves | Arnoldi {ea:+.2%} in {na} solves", flush=True)
        prev = (vp, va)
    for kind in ("cold", "warm"):
        r = np.array([x[1:] for x in rows if x[0] == kind])
        if len(r):
            print(f"{kind}: power error {r[:, 0].min():+.2%}..{r[:, 0].max():+.2%}, median {np.median(r[:, 1]):.0f} "
                  f"solves | Arnoldi error {r[:, 2].min():+.2%}..{r[:, 2].max():+.2%}, median "
                  f"{np.median(r[:, 3]):.0f} solves")


if __name__ == "__main__":
    main()
