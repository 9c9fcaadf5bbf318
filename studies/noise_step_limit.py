"""Which rms noise displacement per step a noisy inextensible run survives: the scan behind ``noise_step``.

    python studies/noise_step_limit.py --N 64 --vertices 2379 --kT 0.405 --noise-step 0.02 0.04 0.08 \
        --seeds 0 1 --steps 300 > scan.md

Each row is the first ``--steps`` steps of the wrinkling case (S, Delta = 0.116, L = 5 R, sharp coupling, harmonic
tension with the mesh ALE, float32, adaptive dt) with thermal noise on; ``noise_step`` caps the step at
dt = (noise_step h)^2 / (2 kT m_self), m_self the markers' self-mobility measured from the noise itself
(``ThermalVelocity.self_mobility``). The run either survives the steps or stops with NumericalInstability (the
step where it stopped is printed). The dt column is the median step taken and the last column the rms noise
displacement per component at that step, sqrt(2 kT dt m_self) / h: where the cap binds it equals noise_step, where
it does not the other limits (flow, tension, growth) were shorter. A limit of the form "displacement per step <=
c h" is supported if the survival threshold in that column is the same across kT and N.

Feeds docs/history/thermal.md, "The noise's step limit (`noise_step`)", and the range of the run parameter
noise_step.
"""

from __future__ import annotations

import argparse
import logging
import tempfile
import time

import numpy as np

from vesicle_core.errors import NumericalInstability
from vesicle_core.geometry import mesh as M
from vesicle_core.model.run_config import legacy_config
from vesicle_core.model.units import chi_from_S
from vesicle_core.solver import simulate


def one(mesh, a, kT, noise_step, seed):
    cfg = legacy_config(chi=chi_from_S(a.S, a.delta), N=a.N, L=5.0, scheme="inextensible", coupling="sharp",
                    tension_space="harmonic", mesh_ale="area", dtype="float32", stretch=1.0, t_end=1.0,
                    output_every=0.02, kT=kT, noise_seed=seed, noise_step=noise_step, fft_workers=1)
    dts = []
    captured = {}

    class _Grab(logging.Handler):  # the run logs its noise limit; keep it
        def emit(self, record):
            if "thermal noise" in record.getMessage():
                captured["dt_noise"] = float(record.args[1])

    handler = _Grab()
    logging.getLogger("vesicle_core.solver.simulate").addHandler(handler)
    logging.getLogger("vesicle_core.solver.simulate").setLevel(logging.INFO)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        r = simulate._Run(mesh, cfg, simulate.Path(tmp), progress=False)
        failed = None
        try:
            while r.steps_this_call < a.steps:  # simulate._Run.loop, keeping each step's length
                _, output_due = r._events()
                X = r.state.X
                F, geo = r.solver.forces(X)
                if output_due:
                    r._output(X, geo)  # also checks the area and volume drift
                rate = cfg.chi * (1.0 if r.state.phase == "stretch" else -1.0)
                t_event = r._step_length(X, geo)
                dts.append(r.dt_step)
                r._advance(X, F, geo, rate, output_due, t_event)
        except NumericalInstability as exc:
            failed = (r.state.step, str(exc)[:60])
    logging.getLogger("vesicle_core.solver.simulate").removeHandler(handler)
    dt_noise = captured.get("dt_noise", np.inf)
    dt_med = float(np.median(dts))
    disp = noise_step * np.sqrt(dt_med / dt_noise)  # the displacement scales as sqrt(dt)
    return dt_med, dt_noise, disp, failed, time.perf_counter() - t0


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--N", type=int, default=64)
    p.add_argument("--vertices", type=int, default=2379)
    p.add_argument("--S", type=float, default=2224.0)
    p.add_argument("--delta", type=float, default=0.116)
    p.add_argument("--kT", type=float, nargs="+", default=[0.405])
    p.add_argument("--noise-step", type=float, nargs="+", default=[1.0, 0.08, 0.04, 0.02])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    p.add_argument("--steps", type=int, default=300)
    a = p.parse_args()
    mesh = M.make_vesicle("quasiuniform", n_vertices=a.vertices, target_delta=a.delta)
    print(f"N = {a.N}, {a.vertices} vertices, S = {a.S:g}, Delta = {a.delta:g}, {a.steps} steps per run\n")
    print("| kT | noise_step | seed | dt_noise [tau] | median dt [tau] | kT dt | rms displacement / h | outcome "
          "| wall [s] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for kT in a.kT:
        for ns in a.noise_step:
            for seed in a.seeds:
                dt, dtn, disp, failed, wall = one(mesh, a, kT, ns, seed)
                out = "survived" if failed is None else f"stopped at step {failed[0]}: {failed[1]}"
                print(f"| {kT:g} | {ns:g} | {seed} | {dtn:.3g} | {dt:.3g} | {kT * dt:.2g} | {disp:.3f} | {out} | "
                      f"{wall:.0f} |", flush=True)


if __name__ == "__main__":
    main()
