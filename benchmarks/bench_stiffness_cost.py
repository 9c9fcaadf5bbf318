"""What a step of ``stiffness: implicit`` costs against the explicit inextensible step, at the same shape and step
length (run by hand; docs/explanation/implicit-stiffness.md, "Cost").

    python benchmarks/bench_stiffness_cost.py RUN_DIR [--frame 49] [--steps 6] [--dt 6e-5]

From a frame of a finished run (its run.yaml and trajectory.nc), the two integrators (each its own solver) take
``--steps`` steps of length ``--dt`` each, interleaved step by step so that the shared machine's load falls on both
alike: each step is next_dt (the limits, and the stabilised scheme's measurements when due) plus step (the tension
solve, the stiffness solve, the mesh ALE). The stabilised scheme's first measurement (the fixed point from a cold
start) and the explicit scheme's first Arnoldi are timed apart, as the once-per-refresh costs. Prints the median wall
time per step of each and their ratio, and the stiffness solve's own time per step.
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
from vesicle_core.solver.schemes import integrator_class
from vesicle_core.solver.trajectory import State


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir")
    ap.add_argument("--frame", type=int, default=49)
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--dt", type=float, default=6e-5)
    a = ap.parse_args(argv)
    cfg0 = load_config(os.path.join(a.run_dir, "run.yaml"))
    ds = xr.open_dataset(os.path.join(a.run_dir, "trajectory.nc"))
    faces = ds.face_node_connectivity.values

    def shape(k):
        return np.stack([ds.node_x.values[k], ds.node_y.values[k], ds.node_z.values[k]], -1)

    rate = float(ds.flow_sign.values[a.frame]) * cfg0.chi
    runs = {}
    for name in ("explicit", "implicit"):
        cfg = dataclasses.replace(cfg0, stiffness=name)
        s = IBMSolver(faces, shape(0), cfg)
        integ = integrator_class(cfg)(s, float(ds.attrs["dt_bending_tau"]), shape(0))
        state = State(X=s.xp.asarray(shape(a.frame)), step=1)
        state.sigma = s.xp.asarray(np.asarray(ds.face_tension.values[a.frame], dtype=float))
        F, geo = s.forces(state.X)
        t0 = time.perf_counter()
        integ._measure_bending(state)
        print(f"{name}: first measurement {time.perf_counter() - t0:.1f} s, {integ.bending_solves} solves, "
              f"limit {integ.bending_limit(state):.4g} tau", flush=True)
        runs[name] = (s, integ, state, [])
    stiff_s = 0.0
    for _ in range(a.steps):
        for name, (s, integ, state, times) in runs.items():
            t0 = time.perf_counter()
            F, geo = s.forces(state.X)
            integ.next_dt(state, geo)
            state.X = state.X + integ.step(state, state.X, F, geo, a.dt, rate)
            state.step += 1
            times.append(time.perf_counter() - t0)
            if name == "implicit":  # the stiffness solve alone, on the force's shape, outside the step's wall
                t1 = time.perf_counter()
                integ.P.solve(a.dt * 1.01, s.be.asnumpy(F))
                stiff_s += time.perf_counter() - t1
    med = {name: float(np.median(r[3])) for name, r in runs.items()}
    print(f"median wall per step: explicit {med['explicit']:.2f} s, implicit {med['implicit']:.2f} s (ratio "
          f"{med['implicit'] / med['explicit']:.3f}); the stiffness solve {stiff_s / a.steps * 1e3:.0f} ms a step "
          f"(a fresh matrix each: an upper bound)")


if __name__ == "__main__":
    main()
