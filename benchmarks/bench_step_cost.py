"""What a step of the default job costs besides its Stokes products, by component (issue 48, item 5).

Run by hand (not a test), with the meshes `vesicle mesh` writes for the default job (config/config.yaml):

    python benchmarks/bench_step_cost.py MESH.nc [MESH.nc ...] [--steps 40] [--warmup 2] [--S 553] [KEY=VALUE ...]
    e.g. python benchmarks/bench_step_cost.py results/meshes/quasiuniform_n9512_s0_D0.116.nc

It runs the default job's discretisation (inextensible scheme, harmonic tension, quality mesh ALE, sharp coupling,
bao6 kernel, float32 grid, N = 128; KEY=VALUE overrides a run parameter) for ``--warmup`` steps (FFT plans, first
solves), then times ``--steps`` more, each component's exclusive wall time (a component called inside another is
subtracted from it). The window from step 2 to 42 holds two bending-limit measurements (steps 20 and 40), as a run
holds one per 20 steps. It wraps the run's own objects, so the same script times an older checkout (PYTHONPATH).

Components:
    Stokes products (step, tension)   IBMMobility.apply: spreading, FFT Stokes solve, interpolation
    Stokes products (bending limit)   IBMSolver.induced_displacement inside the Arnoldi measurement
    bending limit, besides products   the measurement's force differences and Gram-Schmidt
    forces                            the membrane forces and geometry of the step
    tension solve, besides products   the harmonic tension's basis products, G solves, CG vector work
    strain limit                      Inextensible.linearisation_strain (the step's nonlinear area strain)
    mesh ALE (solve)                  the ALE's call (mesh_ale.py; its share is measured, not changed here)
    mesh ALE (carry)                  the ALE's lipid-area transport
    step limits                       next_dt without the bending measurement
    frames                            output frames (trajectory writes, energies)
    other                             the rest of the loop (bookkeeping)

Timings on a shared machine are noisy: compare the shares within one run, and say what else ran (uptime).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

STOKES = ("Stokes products (step, tension)", "Stokes products (bending limit)")


class Clock:
    """Exclusive wall time per component: a wrapped call's time minus that of the wrapped calls it makes."""

    def __init__(self):
        self.seconds, self.calls, self._stack = {}, {}, []

    def wrap(self, name, fn):
        def timed(*a, **kw):
            self._stack.append(0.0)
            t0 = time.perf_counter()
            try:
                return fn(*a, **kw)
            finally:
                dt = time.perf_counter() - t0
                inner = self._stack.pop()
                self.seconds[name] = self.seconds.get(name, 0.0) + dt - inner
                self.calls[name] = self.calls.get(name, 0) + 1
                if self._stack:
                    self._stack[-1] += dt

        return timed


class _TimedALE:
    """The integrator's ALE with its call and its carry timed (a call goes through the type, so a proxy)."""

    def __init__(self, ale, clock):
        self._ale, self._call = ale, clock.wrap("mesh ALE (solve)", ale.__call__)
        self.carry = clock.wrap("mesh ALE (carry)", ale.carry)

    def __call__(self, *a, **kw):
        return self._call(*a, **kw)

    def __getattr__(self, name):
        return getattr(self._ale, name)


def instrument(r, clock):
    integ, solver = r.integ, r.solver
    integ.mobility.apply = clock.wrap(STOKES[0], integ.mobility.apply)
    solver.induced_displacement = clock.wrap(STOKES[1], solver.induced_displacement)
    solver.forces = clock.wrap("forces", solver.forces)
    integ._measure_bending = clock.wrap("bending limit, besides products", integ._measure_bending)
    integ.next_dt = clock.wrap("step limits", integ.next_dt)
    integ.tension.solve = clock.wrap("tension solve, besides products", integ.tension.solve)
    integ.linearisation_strain = clock.wrap("strain limit", integ.linearisation_strain)
    if integ.ale is not None:
        integ.ale = _TimedALE(integ.ale, clock)
    r._output = clock.wrap("frames", r._output)


def profile(mesh_path, steps, warmup, S, extra):
    from vesicle_core.geometry import mesh as M
    from vesicle_core.model.run_config import RunConfig
    from vesicle_core.model.units import chi_from_S
    from vesicle_core.solver.simulate import _Run

    mesh = M.load(mesh_path)
    params = dict(chi=chi_from_S(S, 0.116), N=128, L=5.0, scheme="inextensible", tension_space="harmonic",
                  mesh_ale="quality", coupling="sharp", kernel="bao6", seed_spectrum="thermal", dtype="float32",
                  stretch=1.0, t_end=1.0, output_every=0.02, fft_workers=1)
    params.update(extra)
    cfg = RunConfig.from_dict(params)
    clock = Clock()
    with tempfile.TemporaryDirectory() as d:
        r = _Run(mesh, cfg, Path(d), False)
        r.loop(warmup)
        instrument(r, clock)
        t0 = time.perf_counter()
        r.loop(warmup + steps)
        wall = time.perf_counter() - t0
    clock.seconds["other"] = wall - sum(clock.seconds.values())
    return mesh.n_vertices, wall, clock


def report(nv, steps, wall, clock):
    stokes = sum(clock.seconds.get(k, 0.0) for k in STOKES)
    print(f"\n{nv} vertices, {steps} steps: {wall:.1f} s, {1e3 * wall / steps:.0f} ms per step")
    print(f"{'component':>34} {'ms/step':>8} {'share':>6} {'calls':>6}")
    for k, v in sorted(clock.seconds.items(), key=lambda kv: -kv[1]):
        print(f"{k:>34} {1e3 * v / steps:8.1f} {v / wall:6.1%} {clock.calls.get(k, ''):>6}")
    ale = sum(clock.seconds.get(k, 0.0) for k in ("mesh ALE (solve)", "mesh ALE (carry)"))
    print(f"Stokes products {stokes / wall:.1%} of the wall time (the step's and tension's "
          f"{clock.seconds.get(STOKES[0], 0.0) / wall:.1%}); beside them {1 - stokes / wall:.1%}, of which the "
          f"mesh ALE {ale / wall:.1%} and the rest {(wall - stokes - ale) / wall:.1%}")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("meshes", nargs="+")
    p.add_argument("--steps", type=int, default=40)
    p.add_argument("--warmup", type=int, default=2)
    p.add_argument("--S", type=float, default=553.0)
    a, rest = p.parse_known_args()
    import yaml

    extra = {k: yaml.safe_load(v) for k, v in (kv.split("=", 1) for kv in rest)}
    import vesicle_core

    print(f"{vesicle_core.__file__}; load: {os.getloadavg()}")
    for m in a.meshes:
        nv, wall, clock = profile(m, a.steps, a.warmup, a.S, extra)
        report(nv, a.steps, wall, clock)
    print(f"load: {os.getloadavg()}")


if __name__ == "__main__":
    main()
