"""Is the tension formula the stability limit of the step actually taken? Arnoldi on the frames of a finished run
(run by hand; issue 48, item 2; docs/explanation/implicit-stiffness.md, "The tension's stiffness").

    python benchmarks/bench_tension_stiffness.py RUN_DIR [--frames 49,70] [--stabilised]

RUN_DIR holds a run's run.yaml and trajectory.nc (the inextensible scheme). At each frame, from the same random
start, the stiffest eigenvalue |lam|max of

* J_b = M dF/dX, the bending (and volume penalty) force only: what the run's bending limit measures;
* J_s = M d(F - D^T sigma)/dX at the frame's tension sigma held frozen (step_size.stiffness_product(sigma=...)):
  the bending and the tension's linearised stiffness together, the explicit step's real stability operator up to
  the tension's own response to the displacement;

and the tension formula's rate 2 max|sigma| / (c h) (integrators.TENSION_STABILITY, c = 3.3 sharp, 16 kernel), the
rate at which dt_safety * c h / max|sigma| is dt_safety times the forward-Euler limit 2 / |lam|. Prints for each
mode its share along the vertex normals and the cotan Rayleigh quotient l(l+1) of its normal part (R = 1).
``--full-step DT,...``: the whole velocity map of the step, the tension re-solved (the harmonic solver at
cg_tol 1e-11 on a float64 copy of the solver, no mesh ALE): Arnoldi on dt dU/dX by centred differences, and the
Rayleigh quotient of its stiffest mode (with sign) against -2, forward Euler's edge; G = I + dt dU/dX is the step's
amplification, stable while every eigenvalue of dt dU/dX lies in the disc |1 + z| <= 1.
``--stabilised``: also the critical step of the stabilised step (I + d P)^{-1} J_s with the tension-aware
operator that a run with ``stiffness: implicit`` would build at this frame (implicit_stiffness), by the run's
fixed point d <- 2 / |mu|max.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time

import numpy as np
import xarray as xr

from vesicle_core.geometry.surface import vertex_normals
from vesicle_core.model.run_config import load_config
from vesicle_core.solver.implicit_stiffness import cotan_laplacian
from vesicle_core.solver.integrators import TENSION_STABILITY
from vesicle_core.solver.mobility import IBMSolver
from vesicle_core.solver.step_size import arnoldi, stiffness_product


def describe(v, X, faces):
    """-> (share of the mode along the vertex normals, l(l+1) of its normal part)."""
    v = np.asarray(v, dtype=float)
    n = vertex_normals(X, faces)
    s = np.einsum("ij,ij->i", n, v)
    C, m = cotan_laplacian(X, faces)
    return float(np.linalg.norm(s) / np.linalg.norm(v)), float(s @ (C @ s) / (s @ (m * s)))


def full_step(cfg, faces, X0, X, sigma, rate, dt, v0, iters):
    """Arnoldi on dt dU/dX, U the inextensible scheme's velocity with the tension re-solved (module docstring)."""
    import dataclasses

    from vesicle_core.model.flow import background_velocity
    from vesicle_core.solver.schemes import integrator_class
    from vesicle_core.solver.trajectory import State

    cfg = dataclasses.replace(cfg, dtype="float64", mesh_ale="none", cg_maxiter=1000)
    s = IBMSolver(faces, X0, cfg)
    X = np.asarray(X, dtype=float)
    integ = integrator_class(cfg)(s, 1e-4, X0)
    integ.tension.tol = 1e-11
    state = State(X=X)
    ref = s.membrane.ref.face_area
    c_base = integ.space.fit(np.asarray(sigma, dtype=float))
    solves = [0]

    def velocity(Y, c0):
        F, geo = s.forces(Y)
        integ.mobility.prepare(Y)
        c, _, U = integ.tension_solve(state, geo, F, background_velocity(Y, rate), geo.area - ref, dt, c0.copy(),
                                      None, None, coefficients=True)
        solves[0] += integ.tension.last.iterations + 1
        return U, c

    _, c_base = velocity(X, c_base)
    eps = 1e-5 * float(np.abs(X).max())

    def apply(v):
        return dt * (velocity(X + eps * v, c_base)[0] - velocity(X - eps * v, c_base)[0]) / (2 * eps)

    t0 = time.perf_counter()
    mod, v, n = arnoldi(apply, np.asarray(v0, dtype=float) + 0.0, max_iter=iters, rtol=1e-3, min_iter=5)
    z = float(np.vdot(v, apply(v)) / np.vdot(v, v))
    share, ll = describe(v, X, faces)
    print(f"  full step, dt = {dt:.4g} tau: |z|max of dt dU/dX = {mod:.4g}, its mode's Rayleigh quotient {z:+.4g} "
          f"(forward Euler stable for z >= -2: |lam| = {mod / dt:.5g} /tau, dt_crit ~ {2 * dt / mod:.4g} tau); "
          f"normal share {share:.2f}, l(l+1) = {ll:.0f}; {n} products, {solves[0]} Stokes solves, "
          f"{time.perf_counter() - t0:.0f} s", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir")
    ap.add_argument("--frames", default="49,70", help="comma-separated frame indices")
    ap.add_argument("--iters", type=int, default=40)
    ap.add_argument("--stabilised", action="store_true")
    ap.add_argument("--full-step", default="", help="comma-separated steps dt [tau]")
    a = ap.parse_args(argv)
    cfg = load_config(os.path.join(a.run_dir, "run.yaml"))
    ds = xr.open_dataset(os.path.join(a.run_dir, "trajectory.nc"))
    faces = ds.face_node_connectivity.values

    def shape(k):
        return np.stack([ds.node_x.values[k], ds.node_y.values[k], ds.node_z.values[k]], -1)

    s = IBMSolver(faces, shape(0), cfg)
    c = TENSION_STABILITY[cfg.coupling]
    for k in (int(f) for f in a.frames.split(",")):
        X = s.xp.asarray(shape(k))
        sigma = np.asarray(ds.face_tension.values[k], dtype=float)
        smax = float(np.abs(sigma).max())
        lam_f = 2.0 * smax / (c * cfg.h)
        print(f"frame {k} (gamma_dot t = {float(ds.time[k]):+.2f}): max|sigma| = {smax:.1f}, mean "
              f"{float(ds.tension.values[k]):.1f}; formula rate 2 max|sigma|/({c} h) = {lam_f:.5g} /tau "
              f"(dt_crit {2 / lam_f:.4g} tau); the run's limits (x dt_safety): tension "
              f"{float(ds.dt_limit_tension.values[k]):.4g}, bending {float(ds.dt_limit_bending.values[k]):.4g}",
              flush=True)
        v0 = np.random.default_rng(0).standard_normal(X.shape)
        out = {}
        for name, sig in (("bending only", None), ("frozen tension", sigma)):
            t0 = time.perf_counter()
            lam, v, n = arnoldi(stiffness_product(s, X, sig), s.xp.asarray(v0) + 0.0, max_iter=a.iters, rtol=1e-4,
                                min_iter=5)
            share, ll = describe(s.be.asnumpy(v), np.asarray(shape(k)), faces)
            out[name] = (lam, v)
            print(f"  {name:15s}: |lam|max = {lam:.5g} /tau (dt_crit {2 / lam:.4g} tau; {lam / lam_f:.3f} x the "
                  f"formula's rate), normal share {share:.2f}, l(l+1) = {ll:.0f} (l ~ "
                  f"{(np.sqrt(ll + 0.25) - 0.5):.0f}); {n} solves, {time.perf_counter() - t0:.0f} s", flush=True)
        for dt in (float(d) for d in a.full_step.split(",") if d):
            full_step(cfg, faces, shape(0), X, sigma, float(ds.flow_sign.values[k]) * cfg.chi, dt, v0, a.iters)
        if a.stabilised:
            from vesicle_core.solver.implicit_stiffness import critical_step, tension_operator

            P = tension_operator(np.asarray(shape(k)), faces, cfg, out["bending only"][0], smax)
            J = stiffness_product(s, X, sigma)
            t0 = time.perf_counter()
            d, mu, v, n, it = critical_step(P, J, out["frozen tension"][1], 2.0 / out["frozen tension"][0],
                                            cap=np.inf, xp=s.xp, be=s.be)
            print(f"  stabilised (alpha {P.alpha:.4g}, beta {P.beta:.4g}): critical step {d:.4g} tau = "
                  f"{d * out['frozen tension'][0] / 2:.2f} x the explicit one, {d * lam_f / 2:.2f} x the formula's; "
                  f"{it} fixed-point iterations, {n} solves, {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
