"""Where a step's time goes: cProfile of the first steps of the S = 2224 inextensible run, by stage.

Run by hand:
    python benchmarks/bench_profile.py [N] [N_VERTICES] [STEPS] [KEY=VALUE ...]   # default 256 10242 15
    e.g. python benchmarks/bench_profile.py 128 2562 60 tension_space=harmonic mesh_ale=area

Stages (internal time of the functions): FFT (the backend's r2c/c2r), the spectral Stokes projection
(stokes.py), spreading and interpolation (ibm.py and the scatter/gather NumPy calls they make), stencils, membrane
forces and geometry, the tension solve's own vector work (tension.py), and the rest (setup: FFT plans, the
bending power iteration, output). Quote it with what else ran on the machine.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cProfile
import pstats
import sys
import tempfile
import time

from vesicle_core.geometry import mesh as M
from vesicle_core.model.run_config import legacy_config
from vesicle_core.solver.simulate import run


def stage(path, name):
    if "r2c" in name or "c2r" in name or "pocketfft" in name or "/fft/" in path:
        return "FFT"
    if path.endswith("stokes.py"):
        return "Stokes projection (spectral)"
    if path.endswith("ibm.py") and "spread" in name or name == "_scatter" or "method 'at'" in name:
        return "spread"
    if path.endswith("ibm.py") and "interp" in name or "method 'take'" in name:
        return "interpolate"
    if path.endswith(("kernels.py", "ibm.py")):
        return "stencils"
    if path.endswith("membrane.py"):
        return "membrane forces and geometry"
    if path.endswith("tension.py"):
        return "tension solve (CG vector work)"
    if "mesh_ale.py" in path or "splu" in name or "superlu" in name.lower() or path.endswith(
            "scipy/sparse/_compressed.py"):
        return "mesh_ale (sparse factorisation, sparse products)"
    if path.endswith("tension_harmonic.py") or "cho_solve" in name or "potrs" in name:
        return "harmonic tension (basis products, G solves)"
    return None


def main(N=256, n_vertices=10242, steps=15, **extra):
    mesh = M.make_vesicle("quasiuniform", n_vertices=n_vertices, axes=(1.0, 0.8, 1.0))
    extra.setdefault("fft_workers", 1)
    cfg = legacy_config(chi=267.8, N=N, stretch=1.0, t_end=1.0, output_every=0.02, scheme="inextensible",
                    dtype="float32", **extra)
    pr = cProfile.Profile()
    t = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        pr.enable()
        run(mesh, cfg, d, progress=False, stop_after_steps=steps)
        pr.disable()
    wall = time.perf_counter() - t
    tot = {}
    for (path, _, name), (_, _, tt, _, _) in pstats.Stats(pr).stats.items():
        key = stage(path.replace("\\", "/"), name) or "other (setup, output, Python)"
        tot[key] = tot.get(key, 0.0) + tt
    print(f"N = {N}, {n_vertices} vertices, {steps} steps, {extra or ''}, wall {wall:.1f} s")
    for k, v in sorted(tot.items(), key=lambda kv: -kv[1]):
        print(f"{k:>34}: {v:7.1f} s  {v / wall:6.1%}")


if __name__ == "__main__":
    main(*(int(x) for x in sys.argv[1:4]), **dict(kv.split("=", 1) for kv in sys.argv[4:]))
