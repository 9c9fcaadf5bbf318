"""The harmonic tension's per-step costs and the step's linearisation error on one case, with the solver's
constants set from the command line, so that the settings chosen in docs/history/solver.md ("Fewer solves per step") can
be measured against the earlier ones in one session.

Run by hand:
    python benchmarks/bench_harmonic_step.py [--level 4 | --n-vertices 5762] [--delta 0.116] [--N 128] [--chi 268.2]
        [--ale-damp 1e-3] [--ale-cap 0.05] [--ale-beta 0.1] [--rho per-l|probe] [--rho-refresh 50] [--rho-stale 4]
        [--set dt_strain=1 ...]

The case: a quasi-uniform mesh of 10 4^level + 2 vertices (or --n-vertices) with excess area Delta, `scheme:
inextensible`, `tension_space: harmonic`, `mesh_ale: area`, float32, two FFT threads, 1 + 1 strain units (override
any run parameter with --set). --rho per-l is the earlier measurement (one Stokes solve per l, every 50 steps:
--rho-refresh 50 --rho-stale 1000000); probe the current one. Prints one JSON line: steps, Stokes solves, CG mean /
max, rho_l refreshes, the ALE's seconds, wall time, l_*, l_peak, t_*, and bench_tension_space.py's measures
(constrained and triangle strain, mesh quality, checkerboard), area and volume drift. Quote timings with what else
ran.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import inspect
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

sys.path.insert(0, str(Path(__file__).parent))
from bench_schemes import run_overrides  # noqa: E402
from bench_tension_space import analyse  # noqa: E402

from vesicle_core.analysis.spectra import spectra_from_trajectory  # noqa: E402
from vesicle_core.geometry import mesh as M  # noqa: E402
from vesicle_core.model.run_config import (
    legacy_config,
)
from vesicle_core.solver import mesh_ale as MA  # noqa: E402
from vesicle_core.solver import tension_harmonic as TH  # noqa: E402
from vesicle_core.solver.simulate import run  # noqa: E402


def set_defaults(func, **values):
    """Replace some keyword defaults of ``func`` by name (``__defaults__`` is positional: a tuple written by hand
    shifts onto the wrong parameters once the signature grows)."""
    names = [p.name for p in inspect.signature(func).parameters.values() if p.default is not inspect.Parameter.empty]
    defaults = list(func.__defaults__)
    for name, value in values.items():
        defaults[names.index(name)] = value
    func.__defaults__ = tuple(defaults)


def patch(a):
    """Set the solver's constants for this process: the ALE's Tikhonov weight and step cap (AreaALE, and through
    it ShapeALE and QualityALE), the angle rows' weight and the rho_l measurement."""
    set_defaults(MA.AreaALE.__init__, damp=a.ale_damp, max_step=a.ale_cap)
    set_defaults(MA.QualityALE.__init__, beta=a.ale_beta)
    set_defaults(MA.ShapeALE.__init__, beta=a.ale_beta)
    if a.rho == "per-l":
        TH.EXACT_L = 10**6
    set_defaults(TH.HarmonicTensionSolver.__init__, refresh=a.rho_refresh, stale=a.rho_stale)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=int, default=4)
    ap.add_argument("--n-vertices", type=int, default=None, help="vertex count (default 10 4^level + 2)")
    ap.add_argument("--delta", type=float, default=0.116)
    ap.add_argument("--N", type=int, default=128)
    ap.add_argument("--chi", type=float, default=268.2)
    ap.add_argument("--ale-damp", type=float, default=MA.AreaALE.__init__.__defaults__[0],
                    help="the ALE least squares' Tikhonov weight")
    ap.add_argument("--ale-cap", type=float, default=MA.AreaALE.__init__.__defaults__[1],
                    help="largest tangential ALE step per step, in h")
    ap.add_argument("--ale-beta", type=float, default=MA.QualityALE.__init__.__defaults__[0],
                    help="weight of the shape and quality ALEs' angle rows")
    ap.add_argument("--rho", choices=("probe", "per-l"), default="probe")
    ap.add_argument("--rho-refresh", type=int, default=TH.RHO_REFRESH)
    ap.add_argument("--rho-stale", type=int, default=TH.STALE_ITERATIONS)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--out", default=None, help="keep the run here (default: a temporary directory)")
    a = ap.parse_args()
    patch(a)
    kw = dict(chi=a.chi, N=a.N, scheme="inextensible", tension_space="harmonic", mesh_ale="area", dtype="float32",
              stretch=1.0, t_end=1.0, output_every=0.02, fft_workers=2)
    kw.update(run_overrides(a.set))
    mesh = M.make_vesicle("quasiuniform", n_vertices=a.n_vertices or 10 * 4**a.level + 2, target_delta=a.delta)
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        path = run(mesh, legacy_config(**kw), a.out or d, progress=False)
        wall = time.perf_counter() - t
        ds = xr.open_dataset(path).load()
        spec = spectra_from_trajectory(ds)
        o, _ = analyse(str(path))
    keys = ["steps", "stokes_solves", "cg_iterations_mean", "cg_iterations_max", "tension_rho_refreshes", "ale_s"]
    res = {k: ds.attrs.get(k) for k in keys}
    res.update(wall_s=wall, l_star=float(spec.l_star), l_peak=int(spec.l_peak), t_star=float(spec.t_star),
               constrained_strain_rms=o["constrained_strain_rms"], constrained_strain_max=o["constrained_strain_max"],
               triangle_strain_max=o["triangle_strain_max"], quality_min=o["quality_min"],
               checkerboard_worst_after=o["checkerboard_worst_after"],
               area_drift=float(np.abs(ds.area_drift).max()), volume_drift=float(np.abs(ds.volume_drift).max()))
    res = {k: (v.item() if hasattr(v, "item") else v) for k, v in res.items()}
    print(json.dumps({"args": vars(a), **res}))


if __name__ == "__main__":
    main()
