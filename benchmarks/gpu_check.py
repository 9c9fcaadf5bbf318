"""The first device check: one command that tells whether the CuPy path works on a GPU, how fast and how big it is.

    python benchmarks/gpu_check.py -o gpu_check.json              # on a machine with a GPU and CuPy (<= 8 min, H100)
    python benchmarks/gpu_check.py --stand-in -o gpu_check.json   # anywhere: the strict CuPy stand-in, tiny sizes

Parts (each recorded in the JSON report, each failure recorded there instead of stopping the rest):
1. tests: the strict GPU-path tests (tests/solver/test_strict_gpu_path.py) against real CuPy
   (VESICLE_TEST_REAL_CUPY=1): every shipped discretisation, a resume and ``vesicle decompose`` against NumPy.
2. timings: a steady Stokes solve and one inextensible step of the default job's discretisation (harmonic tension,
   quality ALE, sharp coupling with bao6, float32 grid) at 128^3, 256^3 and 512^3 on icosphere meshes of edge ~h
   (2562, 10242, 40962 vertices), medians of CUDA-event times (the step also as host wall time: its ALE and
   tension coefficients run on the host), and a noisy step's noise field (drawn on the host, copied, transformed).
3. case: the default job's S = 2224 case (config/config.yaml: Delta = 0.116, 9512-vertex quasi-uniform mesh at
   128^3) on CuPy and on NumPy (all CPU cores), l_* of each from the spectra (eq. 31); pass if they agree to 1e-3
   relative.
4. memory: the CuPy memory pool's bytes after the 512^3 timings (the pool keeps what it allocated: its peak).

``--stand-in`` (automatic when no CUDA device is visible) runs all of it on tests/strict_cupy.py at 16^3 and 32^3
and a 162-vertex case of a few steps, so that the first real run finds no import or API error; its timings are the
stand-in's host times and are labelled so (``"timer": "stand-in host clock"``), never GPU numbers.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: default job's discretisation (config/config.yaml), every run parameter the check relies on set here
DEFAULT_RUN = dict(
    L=5.0, scheme="inextensible", tension_space="harmonic", tension_l_max=None, mesh_ale="quality",
    coupling="sharp", kernel="bao6", sharp_floor=0.01, seed_spectrum="thermal", seed=0, seed_scale=1.0,
    dtype="float32", Lambda=None, Re=0.0, dt="power", dt_safety=0.8, dt_growth=0.1, dt_strain=2e-3, cg_tol=1e-5,
    cg_maxiter=200, cg_precond="auto", projection_refresh=10, kT=0.0, area_model="voronoi", K_volume=0.0, K_area=0.0,
    stretch=1.0, t_end=1.0, output_every=0.02, stationary_tol=0.0, max_drift=0.05, checkpoint_every=2000,
    store_velocity=False,
)
REAL_SIZES = {128: 4, 256: 5, 512: 6}  # N -> icosphere level of edge ~h at L = 5 (h = 0.039, 0.0195, 0.0098)
STAND_IN_SIZES = {16: 2, 32: 3}


class Timer:
    """CUDA events on a GPU; on the stand-in the same calls (its Event is a host clock), labelled as such."""

    def __init__(self, cp, real):
        self.cp, self.real = cp, real
        self.label = "cuda-events" if real else "stand-in host clock (not device time)"

    def ms(self, fn, repeats=5, warmup=1):
        """Median (and all) times of fn() in ms, each between two recorded events, and its median host wall time."""
        for _ in range(warmup):
            fn()
        ev, wall = [], []
        for _ in range(repeats):
            a, b = self.cp.cuda.Event(), self.cp.cuda.Event()
            t0 = time.perf_counter()
            a.record()
            fn()
            b.record()
            b.synchronize()
            wall.append(1e3 * (time.perf_counter() - t0))
            ev.append(float(self.cp.cuda.get_elapsed_time(a, b)))
        return {"median_ms": float(np.median(ev)), "all_ms": ev, "wall_median_ms": float(np.median(wall))}


def run_tests(real: bool) -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if real:
        env["VESICLE_TEST_REAL_CUPY"] = "1"
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-k", "strict",
                        str(ROOT / "tests" / "solver" / "test_strict_gpu_path.py")],
                       capture_output=True, text=True, env=env, cwd=ROOT)
    return {"passed": r.returncode == 0, "returncode": r.returncode, "seconds": time.perf_counter() - t0,
            "tail": (r.stdout + r.stderr)[-3000:], "against": "real cupy" if real else "strict stand-in"}


def _time_size(N, level, timer: Timer, repeats: int) -> dict:
    """The Stokes solve and one inextensible step at N^3 (see timings)."""
    from vesicle_core.geometry import mesh as M
    from vesicle_core.model.run_config import RunConfig
    from vesicle_core.solver.fluctuations import ThermalNoise
    from vesicle_core.solver.integrators import Inextensible
    from vesicle_core.solver.mobility import IBMSolver
    from vesicle_core.solver.trajectory import State

    m = M.make_vesicle("icosphere", level=level, axes=(1.0, 0.8, 1.0))
    # at 512^3 (40962 vertices) the default l_t (80: K = 6561 harmonics, a 4 GB dense B on the host) is capped at
    # 40, the default of 10242 vertices, so that the host part of the setup stays within the check's minutes
    params = dict(DEFAULT_RUN, tension_l_max=40) if N >= 512 else DEFAULT_RUN
    cfg = RunConfig(**params, chi=268.2, N=N, backend="cupy", fft_workers=1)
    s = IBMSolver(m.faces, m.vertices, cfg)
    f = s.xp.asarray(np.random.default_rng(0).standard_normal(s.grid.field_shape), dtype=s.be.dtype)
    solve = timer.ms(lambda: s.stokes.velocity(f, out=s._grid_buf), repeats)
    integ = Inextensible(s, 1e-6, X0=m.vertices)  # a short step: one step of the scheme, not its stability
    state = State(X=s.xp.asarray(m.vertices, dtype=s.xp.float64))
    X = state.X

    def one_step():
        F, geo = s.forces(X)
        integ.step(state, X, F, geo, 1e-6, cfg.chi)

    step = timer.ms(one_step, repeats)
    # kT > 0: the step's noise field, drawn on the host (NumPy's Philox, the same numbers as a NumPy run), copied to
    # the device and transformed: what a noisy step adds (docs/howto/gpu-check.md, the transfers)
    noise, steps = ThermalNoise(s.stokes, 0.0405, seed=0), iter(range(1 << 30))
    draw = timer.ms(lambda: noise.displacement(1e-6, next(steps), out=s._grid_buf), repeats)
    return {"n_vertices": int(m.n_vertices), "tension_l_max": int(integ.space.l_max), "stokes_solve": solve,
            "inextensible_step": step, "noise_field": draw, "cg_iterations_last": int(integ.tension.last.iterations)}


def timings(sizes: dict, timer: Timer, repeats: int) -> dict:
    """Per N: a steady Stokes solve and one inextensible step of the default job's discretisation (module docstring);
    each size's arrays are freed before the next (the memory pool keeps their blocks for reuse)."""
    return {str(N): _time_size(N, level, timer, repeats) for N, level in sizes.items()}


def l_star_of(path) -> float:
    from vesicle_core.analysis.spectra import spectra_from_trajectory
    from vesicle_core.data.datasets import open_trajectory

    with open_trajectory(path, require_complete=True) as traj:
        return float(spectra_from_trajectory(traj).l_star)


def case(real: bool, workdir: Path) -> dict:
    """The default job's S = 2224 case on CuPy and NumPy (real), or a 162-vertex few-step stand-in of it."""
    from vesicle_core.geometry import mesh as M
    from vesicle_core.model.run_config import RunConfig
    from vesicle_core.model.units import chi_from_S
    from vesicle_core.solver.simulate import run

    if real:
        m = M.make_vesicle("quasiuniform", level=4, n_vertices=9512, target_delta=0.116)
        params = dict(DEFAULT_RUN, N=128)
    else:
        m = M.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
        params = dict(DEFAULT_RUN, N=16, stretch=0.001, t_end=0.002, output_every=0.001)
    chi = chi_from_S(2224.0, float(m.excess_area()))
    out = {"S": 2224.0, "delta": float(m.excess_area()), "chi": chi, "n_vertices": int(m.n_vertices),
           "N": params["N"]}
    for name, workers in (("cupy", 1), ("numpy", os.cpu_count() or 1)):
        cfg = RunConfig(**params, chi=chi, backend=name, fft_workers=workers)
        t0 = time.perf_counter()
        path = run(m, cfg, workdir / name, progress=False)
        out[f"{name}_wall_s"] = time.perf_counter() - t0
        out[f"{name}_l_star"] = l_star_of(path)
    a, b = out["numpy_l_star"], out["cupy_l_star"]
    out["relative_difference"] = abs(b - a) / abs(a) if a else math.inf
    out["passed"] = bool(out["relative_difference"] <= 1e-3)
    return out


def memory(cp) -> dict:
    pool = cp.get_default_memory_pool()
    return {"pool_total_bytes": int(pool.total_bytes()), "pool_used_bytes": int(pool.used_bytes()),
            "note": "the CuPy pool keeps the blocks it allocated, so total_bytes after the largest size is its peak"}


def _part(report, name, fn):
    t0 = time.perf_counter()
    try:
        report[name] = fn()
    except Exception as exc:  # the report says what failed; the other parts still run
        report[name] = {"error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc()[-3000:]}
    report[name + "_seconds"] = time.perf_counter() - t0
    print(f"[gpu_check] {name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("-o", "--output", default="gpu_check.json", help="JSON report (written atomically)")
    p.add_argument("--stand-in", action="store_true", help="run on the strict CuPy stand-in at tiny sizes")
    p.add_argument("--skip", nargs="*", default=[], choices=("tests", "timings", "case", "memory"),
                   help="parts to leave out")
    p.add_argument("--repeats", type=int, default=5, help="timed repeats per size (median reported)")
    p.add_argument("--sizes", type=int, nargs="+", default=None,
                   help="grid sizes N to time (default 128 256 512 on a GPU, 16 32 on the stand-in)")
    a = p.parse_args(argv)

    from vesicle_core.solver.backend import cupy_available

    real = not a.stand_in and cupy_available()
    if real:
        import cupy as cp
    else:
        sys.path.insert(0, str(ROOT / "tests"))
        from strict_cupy import make_modules

        cp, cpx = make_modules()
        sys.modules["cupy"], sys.modules["cupyx"] = cp, cpx
    timer = Timer(cp, real)
    report = {"device": "gpu" if real else "strict CuPy stand-in (host; no GPU numbers)", "timer": timer.label,
              "python": platform.python_version(), "numpy": np.__version__, "host": platform.node(),
              "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    if real:
        props = cp.cuda.runtime.getDeviceProperties(0)
        report.update(cupy=cp.__version__, gpu_name=props["name"].decode(),
                      gpu_total_bytes=int(props["totalGlobalMem"]))
        cp.get_default_memory_pool().free_all_blocks()
    sizes = REAL_SIZES if real else STAND_IN_SIZES
    if a.sizes:
        known = {**STAND_IN_SIZES, **REAL_SIZES}
        bad = [n for n in a.sizes if n not in known]
        if bad:
            p.error(f"--sizes: {bad} not among {sorted(known)}")
        sizes = {n: known[n] for n in a.sizes}
    if "tests" not in a.skip:
        _part(report, "tests", lambda: run_tests(real))
    if "timings" not in a.skip:
        _part(report, "timings", lambda: timings(sizes, timer, a.repeats))
    if "memory" not in a.skip:
        _part(report, "memory", lambda: {**memory(cp), "after_size": max(sizes)})
    if "case" not in a.skip:
        with tempfile.TemporaryDirectory() as d:
            _part(report, "case", lambda: case(real, Path(d)))
    if not real:
        report["stand_in_transfers"] = cp.transfers.snapshot()
    out = Path(a.output)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(report, indent=2, default=str))
    os.replace(tmp, out)
    failed = [k for k in ("tests", "timings", "case", "memory") if isinstance(report.get(k), dict)
              and ("error" in report[k] or report[k].get("passed") is False)]
    print(f"[gpu_check] wrote {out}; " + (f"FAILED: {failed}" if failed else "all parts ran"), file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
