"""``vesicle stochastic-pa | noise``: noisy ensembles (issue 49): the stochastic PA of one point, and the sweep's
ensemble analysis and figures from the catalog.

Registered in :mod:`vesicle_core.cli`; each ``add_<command>(sub)`` adds one subparser whose ``func`` takes the parsed
arguments and returns the exit status 0.
"""

from __future__ import annotations

import math
import os

from ..model.resolution import DEFAULT_KERNEL, KERNELS
from .args import int_in, positive_float


# --------------------------------------------------------------------------- stochastic-pa
def add_stochastic_pa(sub):
    p = sub.add_parser("stochastic-pa", help="stochastic PA (eqs. 11-12 with thermal forcing) over an ensemble of "
                                             "seeds -> per-seed l_*, l_peak, t_*")
    p.add_argument("--delta", type=positive_float("--delta"), required=True, help="excess area Delta > 0")
    p.add_argument("--S", type=positive_float("--S"), required=True, help="flow strength S > 0")
    p.add_argument("--kT", type=positive_float("--kT"), required=True, help="k_B T / kappa > 0 (0.0405 at 293 K)")
    p.add_argument("--seeds", type=int_in("--seeds", 2, 10000), default=16, help="ensemble size (seeds 0..n-1)")
    p.add_argument("--n-steps", type=int_in("--n-steps", 10, 10**7), default=4000, help="steps after the reversal")
    p.add_argument("--l-max", type=int_in("--l-max", 4, 400), default=None, help="truncation (default: from S)")
    p.add_argument("--grid-N", type=int_in("--grid-N", 0, 4096), default=0,
                   help="the PA on an IBM grid of N^3 cells over a box of edge --L (rates damped by "
                        "theory.grid_damping); 0: the continuum (default)")
    p.add_argument("--L", type=positive_float("--L"), default=5.0, help="box edge of --grid-N, in R (default 5)")
    p.add_argument("--kernel", choices=sorted(KERNELS), default=DEFAULT_KERNEL, help="kernel of --grid-N")
    p.add_argument("--coupling", choices=("kernel", "sharp"), default="kernel", help="coupling of --grid-N")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    p.set_defaults(func=_cmd_stochastic_pa)


def _cmd_stochastic_pa(a):
    from ..analysis.noise_tables import stochastic_pa_dataset
    from ..analysis.stochastic_pa import simulate
    from ..data.datasets import cf_attrs, write_dataset

    grid = {"grid_h": a.L / a.grid_N, "kernel": a.kernel, "coupling": a.coupling} if a.grid_N else {}
    run = simulate(a.delta, a.S, seeds=range(a.seeds), kT_over_kappa=a.kT, l_max=a.l_max, n_steps=a.n_steps, **grid)
    ds = stochastic_pa_dataset(run, N=a.grid_N, L=a.L if a.grid_N else math.nan,
                               kernel=a.kernel if a.grid_N else "", coupling=a.coupling if a.grid_N else "",
                               n_steps=a.n_steps)
    ds.attrs = cf_attrs("vesicle-wrinkling: stochastic perturbation analysis ensemble", **ds.attrs)
    write_dataset(ds, a.output)
    s = run.summary()
    print(f"wrote {a.output}: {s['n_seeds']} seeds, l_* = {s['l_star']:.4g} +- {s['l_star_sd']:.2g}, "
          f"t_* = {s['t_star']:.4g} +- {s['t_star_sd']:.2g}")
    return 0


# --------------------------------------------------------------------------- noise analyse | figures
def add_noise(sub):
    p = sub.add_parser("noise", help="noisy ensembles: analysis and figures from the catalog")
    ns = p.add_subparsers(dest="noise_command", required=True)
    an = ns.add_parser("analyse", help="per-point mean +- sd, the exponent by seed bootstrap, l_* per decade of kT, "
                                       "the excess over the stochastic PA, the convergence check -> ensembles.nc")
    an.add_argument("catalog", help="results/catalog.csv (its spectra rows are read)")
    an.add_argument("--pa", nargs="*", default=[], help="stochastic PA datasets ('vesicle stochastic-pa')")
    an.add_argument("--n-boot", type=int_in("--n-boot", 10, 10**6), default=2000, help="bootstrap replicates")
    an.add_argument("--confidence", type=positive_float("--confidence"), default=0.95, help="interval level")
    an.add_argument("-o", "--output", required=True, help="output netCDF file")
    an.set_defaults(func=_cmd_analyse)
    fg = ns.add_parser("figures", help="Fig. 4 and Figs. 3/5 with noise, histograms of l_* per point")
    fg.add_argument("ensembles", help="ensembles.nc ('vesicle noise analyse')")
    fg.add_argument("--catalog", required=True, help="results/catalog.csv (the runs' spectra for the bands)")
    fg.add_argument("--pa", nargs="*", default=[], help="stochastic PA datasets")
    fg.add_argument("--fit", default=None, help="fit.nc of 'vesicle fit' (the deterministic PA of Fig. 4)")
    fg.add_argument("--outdir", required=True, help="directory of the figures")
    fg.add_argument("--dpi", type=int_in("--dpi", 30, 1200), default=150)
    fg.set_defaults(func=_cmd_figures)


def _spectra_rows(catalog):
    """The catalog's spectra rows as analysis rows (l_peak read from each file)."""
    import xarray as xr

    from ..data.catalog import read_catalog

    rows = []
    for r in read_catalog(catalog):
        if r["kind"] != "spectra":
            continue
        with xr.open_dataset(r["abspath"], engine="netcdf4") as ds:
            l_peak = float(ds["l_peak"]) if "l_peak" in ds else math.nan
            rows.append({"delta": r["Delta"], "S": r["S"], "N": int(r["N"] or 0), "vertices": int(r["n_vertices"] or 0),
                         "kT": 0.0 if not r["kT"] > 0 else float(r["kT"]), "noise_seed": int(r["noise_seed"] or 0),
                         "l_star": float(ds["l_star"]), "l_peak": l_peak, "t_star": float(ds["t_star"]),
                         "case_id": r["case_id"], "path": r["abspath"]})
    return rows


def _open_all(paths):
    import xarray as xr

    out = []
    for p in paths:
        with xr.open_dataset(p, engine="netcdf4") as ds:
            out.append(ds.load())
    return out


def _cmd_analyse(a):
    from ..analysis.noise_tables import ensemble_dataset
    from ..data.datasets import cf_attrs, write_dataset

    ds = ensemble_dataset(_spectra_rows(a.catalog), _open_all(a.pa), n_boot=a.n_boot, confidence=a.confidence)
    ds.attrs = cf_attrs("vesicle-wrinkling: noisy ensembles", **ds.attrs)
    write_dataset(ds, a.output)
    print(f"wrote {a.output}: {ds.sizes['point']} noisy points, {ds.sizes.get('exponent', 0)} exponents, "
          f"{ds.sizes.get('kt_scan', 0)} kT scans, {ds.sizes.get('rung', 0)} convergence checks")
    return 0


def _cmd_figures(a):
    import xarray as xr

    from ..viz import noise_figures as NF

    with xr.open_dataset(a.ensembles, engine="netcdf4") as ds:
        ens = ds.load()
    fit = _open_all([a.fit])[0] if a.fit else None
    pas = _open_all(a.pa)
    rows = _spectra_rows(a.catalog)
    os.makedirs(a.outdir, exist_ok=True)
    out = NF.plot_lstar_noise(ens, fit, os.path.join(a.outdir, "lstar_vs_S.png"), dpi=a.dpi)
    out += NF.plot_lstar_histograms(ens, pas, os.path.join(a.outdir, "lstar_hist.png"), dpi=a.dpi)
    for pid, members in NF.point_members(rows).items():
        det = NF.deterministic_twin(rows, members[0])
        out += NF.plot_dynamics_noise(_open_all([r["path"] for r in members]),
                                      _open_all([det["path"]])[0] if det else None,
                                      NF.matching_pa(pas, members[0]), os.path.join(a.outdir, f"dynamics_{pid}.png"),
                                      dpi=a.dpi)
    print("wrote " + ", ".join(str(p) for p in out))
    return 0
