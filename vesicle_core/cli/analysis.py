"""``vesicle decompose | theory | fit``: the analysis subcommands (spectra of a run, the PA reference, sweep fits).

Registered in :mod:`vesicle_core.cli`; each ``add_<command>(sub)`` adds one subparser whose ``func`` takes the parsed
arguments and returns the exit status 0.
"""

from __future__ import annotations

import os
import sys

from ..analysis.harmonics import FITS
from ..errors import check_range
from ..model.resolution import DEFAULT_KERNEL, KERNELS
from .args import int_in, positive_float


# --------------------------------------------------------------------------- decompose
def add_decompose(sub):
    p = sub.add_parser("decompose", help="spherical-harmonic spectra of a trajectory (eqs. 30-32) -> spectra.nc")
    p.add_argument("trajectory", help="trajectory.nc written by 'vesicle run'")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    p.add_argument("--l-max", type=int_in("--l-max", 2, 512), default=None,
                   help="largest degree (default: what the mesh resolves, at most 64)")
    p.add_argument("--stride", type=int_in("--stride", 1, 10**6), default=1, help="analyse every k-th frame")
    p.add_argument("--fit", choices=FITS, default="quadrature",
                   help="how coefficients are read off the mesh: the quadrature sum of eq. (30), or its least-squares "
                        "refinement, which removes the quadrature's aliasing floor on irregular (quasi-uniform) meshes "
                        "at ~4x the time (harmonics module docstring, 'Fit') (default quadrature)")
    p.add_argument("--map", type=int_in("--map", 4, 1024), nargs=2, metavar=("NTHETA", "NPHI"), default=None,
                   help="also store A_p(theta, phi) maps on an NTHETA x NPHI grid")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_cmd_decompose)


def _cmd_decompose(a):
    from ..analysis.spectra import spectra_from_trajectory
    from ..data.datasets import open_trajectory, write_dataset

    with open_trajectory(a.trajectory, require_complete=True) as traj:
        ds = spectra_from_trajectory(traj, l_max=a.l_max, stride=a.stride, progress=not a.quiet, fit=a.fit,
                                     map_shape=tuple(a.map) if a.map else None, command=" ".join(sys.argv))
    write_dataset(ds, a.output)
    print(f"wrote {a.output}: {ds.sizes['time']} frames, l_max {ds.sizes['l'] - 1}, "
          f"t_* = {float(ds.t_star):.4g}, l_* = {float(ds.l_star):.4g}")
    return 0


# --------------------------------------------------------------------------- theory
_CF_KEYS = ("Conventions", "title", "source", "history")


def _set_cf(ds, title):
    """Replace a dataset's global attributes by the CF set plus its own parameters (the producer's
    ``source`` is kept as ``generator``)."""
    from ..data.datasets import cf_attrs

    params = {k: v for k, v in ds.attrs.items() if k not in _CF_KEYS}
    if "source" in ds.attrs:
        params.setdefault("generator", ds.attrs["source"])
    ds.attrs = cf_attrs(title, **params)


def add_theory(sub):
    p = sub.add_parser("theory", help="perturbation analysis (eqs. 11-12) of the same case -> theory.nc")
    p.add_argument("--delta", type=positive_float("--delta"), required=True, help="excess area Delta > 0")
    p.add_argument("--S", type=positive_float("--S"), required=True, help="flow strength S > 0")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    p.add_argument("--l-max", type=int_in("--l-max", 4, 400), default=None, help="largest degree (default: from S)")
    p.add_argument("--seed", type=int_in("--seed", 0, 2**31 - 1), default=0, help="seed of the thermal phases")
    p.add_argument("--n-out", type=int_in("--n-out", 10, 100000), default=401, help="output times")
    p.add_argument("--no-modes", action="store_true", help="do not store u_lm(t) (smaller file)")
    p.add_argument("--grid-h", type=positive_float("--grid-h"), default=None,
                   help="the PA as an IBM grid of this spacing (in R) carries it: every mode's rates times the "
                        "kernel's measured damping (theory.grid_damping); default: the continuum")
    p.add_argument("--kernel", choices=sorted(KERNELS), default=DEFAULT_KERNEL, help="kernel of --grid-h")
    p.add_argument("--coupling", choices=("kernel", "sharp"), default="kernel", help="coupling of --grid-h")
    p.set_defaults(func=_cmd_theory)


def _cmd_theory(a):
    from ..analysis.theory import run_theory
    from ..data.datasets import write_dataset

    ds = run_theory(a.delta, a.S, l_max=a.l_max, seed=a.seed, n_out=a.n_out, store_modes=not a.no_modes,
                    grid_h=a.grid_h, kernel=a.kernel if a.grid_h else None,
                    coupling=a.coupling if a.grid_h else None)
    _set_cf(ds, "perturbation analysis of a quasi-spherical vesicle after a flow reversal")
    write_dataset(ds, a.output)
    print(f"wrote {a.output}: t_* = {float(ds.t_star):.4g}, l_* (eq. 31) = {float(ds.l_star):.4g}, "
          f"l_peak = {float(ds.l_peak):.4g}")
    return 0


# --------------------------------------------------------------------------- fit
def add_fit(sub):
    p = sub.add_parser("fit", help="power laws across a sweep: l_* ~ S^b and stage-2 tension decay -> fit.nc")
    p.add_argument("inputs", nargs="+", help="spectra.nc and/or theory.nc files")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    p.add_argument("--confidence", type=float, default=0.95, help="confidence level in (0, 1) (default 0.95)")
    p.set_defaults(func=_cmd_fit)


def _cmd_fit(a):
    import numpy as np

    from ..analysis.sweep_fits import sweep_fit_dataset
    from ..data.datasets import read_dataset, write_dataset

    check_range("--confidence", a.confidence, 0.0, 1.0, lo_open=True, hi_open=True)
    dss = []
    for path in a.inputs:
        ds = read_dataset(path, required=("l_star", "t_star", "sigma"))
        # runs live in results/runs/<case_id>/spectra.nc, PA references in results/theory/<theory_id>.nc
        parent = os.path.basename(os.path.dirname(os.path.abspath(path)))
        stem = os.path.splitext(os.path.basename(path))[0]
        ds.attrs.setdefault("case_id", stem if stem not in ("spectra", "theory") else parent)
        dss.append(ds)
    out = sweep_fit_dataset(dss, confidence=a.confidence)
    out.attrs["inputs"] = " ".join(a.inputs)
    _set_cf(out, "power-law fits across a vesicle-wrinkling sweep")
    write_dataset(out, a.output)
    for i in range(out.sizes["group"]):
        g = out.isel(group=i)
        hot = f" kT={float(g.group_kT):g}" if float(g.group_kT) > 0 else ""
        N = int(g.group_N)
        grid = "" if N == 0 else " N=finest at each S" if N < 0 else f" N={N} ({int(g.group_vertices)} vertices)"
        print(f"{str(g.group_kind.values):>10} Delta={float(g.group_delta):g}{grid}{hot} n={int(g.n_cases)}: "
              f"l_* ~ S^{float(g.l_star_exponent):.3f} [{float(g.l_star_ci_low):.3f}, {float(g.l_star_ci_high):.3f}], "
              f"l_peak ~ S^{float(g.l_peak_exponent):.3f}")
    for i in np.flatnonzero(out["point_n_seeds"].values > 1):
        p = out.isel(point=i)
        print(f"  ensemble S={float(p.point_S):g}: {int(p.point_n_seeds)} seeds, l_* = {float(p.point_l_star_mean):.2f}"
              f" +- {float(p.point_l_star_sd):.2f} (sd), t_* = {float(p.point_t_star_mean):.3f} +- "
              f"{float(p.point_t_star_sd):.3f}")
    print(f"wrote {a.output}")
    return 0
