"""The noisy sweep's numbers as datasets: the stochastic PA ensemble of one point (:func:`stochastic_pa_dataset`,
written by ``vesicle stochastic-pa``) and the whole sweep's ensemble analysis (:func:`ensemble_dataset`, written by
``vesicle noise analyse``). The statistics themselves are :mod:`vesicle_core.analysis.noise_ensembles`.

``ensemble_dataset`` layout (one row per group along each dimension):

    point      one IBM ensemble: (Delta, S, N, vertices, kT > 0), its seeds along ``seed`` (NaN-padded): l_star,
               l_peak, t_star per seed and their mean / sd / se; the deterministic IBM at the same (Delta, S, N,
               vertices) (``det_l_star``, NaN if not run); the stochastic PA beside it, in the continuum (``pa_``)
               and on the run's grid (``gpa_``), mean / sd / n of each; the IBM's excess over each with its se
    exponent   l_* ~ S^b of one (source, Delta, N, vertices, kT): source "ibm" (the ensembles, seed bootstrap),
               "pa" and "gpa" (the stochastic PA, same bootstrap over its seeds), "ibm_det" (the deterministic runs,
               OLS with a Student-t interval; needs 3 S)
    kt_scan    l_* per decade of kT at one (Delta, S, N, vertices) run at >= 2 kT (IBM; and the continuum PA)
    rung       the convergence check of a noisy (Delta, S, kT) run at two resolutions: each rung against the next
               finer one
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from .fits import fit_power_law
from .noise_ensembles import bootstrap_exponent, converged, excess, kT_slope, point_stats

__all__ = ["stochastic_pa_dataset", "ensemble_dataset", "pa_key"]


def stochastic_pa_dataset(run, *, N=0, L=math.nan, kernel="", coupling="", n_steps=0):
    """One :class:`stochastic_pa.StochasticPA` ensemble as a Dataset: per seed l_star, l_peak, t_star,
    Delta_l_at_t_star (seed, l) and the series Delta_2, sigma (seed, time); attrs delta, S, chi, kT, l_max and the
    grid (N = 0: the continuum)."""
    import xarray as xr

    seeds = np.asarray(run.seeds, dtype=int)
    ds = xr.Dataset(
        {
            "l_star": ("seed", np.asarray(run.l_star, dtype=float)),
            "l_peak": ("seed", np.asarray(run.l_peak, dtype=float)),
            "t_star": ("seed", np.asarray(run.t_star, dtype=float)),
            "Delta_l_at_t_star": (("seed", "l"), np.asarray(run.Delta_l_star, dtype=float)),
            "Delta_2": (("seed", "time"), np.asarray(run.Delta_2, dtype=float)),
            "sigma": (("seed", "time"), np.asarray(run.sigma, dtype=float)),
        },
        coords={"seed": seeds, "l": np.arange(run.l_max + 1), "time": np.asarray(run.t, dtype=float)},
    )
    ds["l_star"].attrs["long_name"] = "l_* of eq. (31) at each seed's t_* (3 <= l <= l_max)"
    ds["l_peak"].attrs["long_name"] = "argmax_{l>=3} Delta_l at t_*"
    ds["t_star"].attrs.update(units="1/gamma_dot", long_name="argmin Delta_2 after the reversal")
    ds["time"].attrs.update(units="1/gamma_dot", long_name="gamma_dot (t - t0)")
    ds["sigma"].attrs["units"] = "kappa/R^2"
    ds.attrs.update(delta=float(run.delta), S=float(run.S), chi=float(run.chi), kT=float(run.kT_over_kappa),
                    l_max=int(run.l_max), noise=run.noise, grid_N=int(N), grid_L=float(L), kernel=str(kernel),
                    coupling=str(coupling), n_steps=int(n_steps), sum_u2_error=float(run.sum_u2_error),
                    model="stochastic PA, eqs. (11)-(12) with thermal forcing (analysis.stochastic_pa)")
    return ds


def _k(x):
    return float(f"{float(x):.6g}")


def pa_key(delta, S, kT, N=0):
    """Key matching a stochastic PA dataset to a point: (Delta, S, kT, grid N; 0 for the continuum)."""
    return (_k(delta), _k(S), _k(kT), int(N))


def _pa_index(pa_datasets):
    out = {}
    for ds in pa_datasets:
        a = ds.attrs
        key = pa_key(a["delta"], a["S"], a["kT"], a.get("grid_N", 0))
        if key in out:
            raise ConfigError(f"two stochastic PA datasets for Delta={key[0]}, S={key[1]}, kT={key[2]}, N={key[3]}")
        out[key] = {n: np.asarray(ds[n].values, dtype=float) for n in ("l_star", "l_peak", "t_star")}
    return out


def _points(rows):
    """Noisy simulation rows grouped per (Delta, S, N, vertices, kT), sorted."""
    groups = {}
    for r in rows:
        if r["kT"] > 0:
            key = (_k(r["delta"]), _k(r["S"]), int(r["N"]), int(r["vertices"]), _k(r["kT"]))
            groups.setdefault(key, []).append(r)
    return dict(sorted(groups.items()))


_MEASURES = ("l_star", "l_peak", "t_star")


def _point_table(points, rows, pas):
    det = {(_k(r["delta"]), _k(r["S"]), int(r["N"]), int(r["vertices"])): r["l_star"] for r in rows if r["kT"] == 0}
    n_seed = max(len(v) for v in points.values())
    t = {k: [] for k in ("delta", "S", "N", "vertices", "kT", "n_seeds", "det_l_star", "seed_id")}
    for name in _MEASURES:
        t[f"{name}_seed"] = []
        for stat in ("mean", "sd", "se"):
            t[f"{name}_{stat}"] = []
    for src in ("pa", "gpa"):
        for k in ("n_seeds", "l_star_mean", "l_star_sd", "l_peak_mean", "t_star_mean", "excess", "excess_se"):
            t[f"{src}_{k}"] = []
    for (delta, S, N, nv, kT), members in points.items():
        members = sorted(members, key=lambda r: r["noise_seed"])
        for name, v in zip(("delta", "S", "N", "vertices", "kT", "n_seeds"), (delta, S, N, nv, kT, len(members)),
                           strict=True):
            t[name].append(v)
        t["det_l_star"].append(det.get((delta, S, N, nv), math.nan))
        pad = [math.nan] * (n_seed - len(members))
        t["seed_id"].append([float(r["noise_seed"]) for r in members] + pad)
        for name in _MEASURES:
            vals = [float(r[name]) for r in members]
            t[f"{name}_seed"].append(vals + pad)
            s = point_stats(vals)
            t[f"{name}_mean"].append(s.mean)
            t[f"{name}_sd"].append(s.sd)
            t[f"{name}_se"].append(s.se)
        for src, grid in (("pa", 0), ("gpa", N)):
            pa = pas.get(pa_key(delta, S, kT, grid))
            if pa is None:
                for k in ("n_seeds", "l_star_mean", "l_star_sd", "l_peak_mean", "t_star_mean", "excess", "excess_se"):
                    t[f"{src}_{k}"].append(0 if k == "n_seeds" else math.nan)
                continue
            s = point_stats(pa["l_star"])
            e = excess([r["l_star"] for r in members], pa["l_star"])
            for k, v in (("n_seeds", s.n), ("l_star_mean", s.mean), ("l_star_sd", s.sd),
                         ("l_peak_mean", float(np.nanmean(pa["l_peak"]))),
                         ("t_star_mean", float(np.nanmean(pa["t_star"]))), ("excess", e.excess), ("excess_se", e.se)):
                t[f"{src}_{k}"].append(v)
    out = {}
    for k, v in t.items():
        out[f"point_{k}" if not k.startswith("point") else k] = (("point", "seed") if k.endswith("_seed")
                                                               or k == "seed_id" else "point", np.array(v))
    return out


def _exponent_table(points, rows, pas, n_boot, confidence):
    t = {k: [] for k in ("source", "delta", "N", "vertices", "kT", "n_S", "exponent", "ci_low", "ci_high")}

    def add(src, key, fit, n_S):
        for k, v in zip(("source", "delta", "N", "vertices", "kT", "n_S"), (src, *key, n_S), strict=True):
            t[k].append(v)
        for k in ("exponent", "ci_low", "ci_high"):
            t[k].append(getattr(fit, k) if fit is not None else math.nan)

    series = {}
    for (delta, S, N, nv, kT), members in points.items():
        series.setdefault(("ibm", delta, N, nv, kT), []).append((S, [r["l_star"] for r in members]))
        for src, grid in (("pa", 0), ("gpa", N)):
            pa = pas.get(pa_key(delta, S, kT, grid))
            if pa is not None:
                series.setdefault((src, delta, grid, 0 if src == "pa" else nv, kT), []).append((S, pa["l_star"]))
    for (src, *key), pts in sorted(series.items(), key=lambda kv: tuple(map(str, kv[0]))):
        pts = sorted(dict(pts).items())  # one entry per S (the PA of one grid is shared by the rungs' vertex counts)
        fit = None
        if len(pts) >= 2 and all(np.isfinite(v).sum() >= 2 for _, v in pts):
            fit = bootstrap_exponent([s for s, _ in pts], [v for _, v in pts], n_boot=n_boot, confidence=confidence)
        add(src, tuple(key), fit, len(pts))
    det = {}
    for r in rows:
        if r["kT"] == 0:
            det.setdefault((_k(r["delta"]), int(r["N"]), int(r["vertices"])), {})[_k(r["S"])] = r["l_star"]
    for (delta, N, nv), by_S in sorted(det.items()):
        fit = None
        if len(by_S) >= 3:
            S, y = map(np.asarray, zip(*sorted(by_S.items()), strict=True))
            fit = fit_power_law(S, y, confidence)
        add("ibm_det", (delta, N, nv, 0.0), fit, len(by_S))
    return {f"exponent_{k}" if k != "source" else "exponent_source": ("exponent", np.array(v)) for k, v in t.items()}


def _kt_table(points, pas):
    t = {k: [] for k in ("source", "delta", "S", "N", "vertices", "n_kT", "slope", "slope_se")}
    scans = {}
    for (delta, S, N, nv, kT), members in points.items():
        scans.setdefault(("ibm", delta, S, N, nv), {})[kT] = [r["l_star"] for r in members]
        pa = pas.get(pa_key(delta, S, kT, 0))
        if pa is not None:
            scans.setdefault(("pa", delta, S, 0, 0), {})[kT] = pa["l_star"]
    for (src, delta, S, N, nv), by_kT in sorted(scans.items(), key=lambda kv: tuple(map(str, kv[0]))):
        if len(by_kT) < 2:
            continue
        kT, samples = zip(*sorted(by_kT.items()), strict=True)
        f = kT_slope(kT, samples)
        for k, v in zip(t, (src, delta, S, N, nv, f.n_kT, f.slope, f.slope_se), strict=True):
            t[k].append(v)
    return {f"kt_{k}": ("kt_scan", np.array(v)) for k, v in t.items()}


def _rung_table(points):
    t = {k: [] for k in ("delta", "S", "kT", "N", "vertices", "N_fine", "vertices_fine", "rel_diff", "diff",
                         "se_diff", "met")}
    ladders = {}
    for (delta, S, N, nv, kT), members in points.items():
        ladders.setdefault((delta, S, kT), []).append(((N, nv), [r["l_star"] for r in members]))
    for (delta, S, kT), rungs in sorted(ladders.items()):
        rungs.sort(key=lambda r: r[0])
        for (c_res, c), (f_res, f) in zip(rungs, rungs[1:], strict=False):
            if len(c) < 2 or len(f) < 2:
                continue
            cv = converged(c, f)
            for k, v in zip(t, (delta, S, kT, *c_res, *f_res, cv.rel_diff, cv.diff, cv.se_diff, int(cv.met)),
                            strict=True):
                t[k].append(v)
    return {f"rung_{k}": ("rung", np.array(v)) for k, v in t.items()}


def ensemble_dataset(rows, pa_datasets=(), *, n_boot=2000, confidence=0.95):
    """The noisy sweep's analysis (module docstring). ``rows``: one dict per simulation with delta, S, N, vertices,
    kT, noise_seed, l_star, l_peak, t_star (kT = 0: deterministic); ``pa_datasets``: :func:`stochastic_pa_dataset`
    outputs. Needs at least one noisy point."""
    import xarray as xr

    points = _points(rows)
    if not points:
        raise ConfigError("ensemble_dataset: no noisy runs (kT > 0) among the datasets")
    pas = _pa_index(pa_datasets)
    data = {**_point_table(points, rows, pas), **_exponent_table(points, rows, pas, n_boot, confidence),
            **_kt_table(points, pas), **_rung_table(points)}
    out = xr.Dataset(data)
    out["point_l_star_sd"].attrs["long_name"] = "sample standard deviation of l_* over the noise seeds"
    out["point_gpa_excess"].attrs["long_name"] = "IBM ensemble mean l_* / stochastic PA on the run's grid - 1"
    out["exponent_ci_low"].attrs["long_name"] = f"lower end of the {confidence:.0%} interval of the exponent"
    out.attrs.update(confidence=float(confidence), n_boot=int(n_boot),
                     method="seed bootstrap within each S (noise_ensembles.bootstrap_exponent); WLS slope per decade "
                            "of kT; delta-method excess; convergence: < 3% or < 2 se of the difference")
    return out
