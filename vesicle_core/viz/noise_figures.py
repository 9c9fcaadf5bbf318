"""Figures of the noisy ensembles (issue 49), in the style of :mod:`vesicle_core.viz.plots`:

    plot_lstar_noise(ens, fit, outputs)          Fig. 4 with noise: the IBM ensembles' mean with a +-sd band per S,
                                                 beside the deterministic IBM, the PA and the stochastic PA
                                                 (continuum and on the run's grid)
    plot_dynamics_noise(sims, det, pa, outputs)  Fig. 3/5 with noise: sigma(t), Delta_2(t) and Delta_l*(t) of one
                                                 point as ensemble bands (mean +- sd over the seeds), beside the
                                                 deterministic run and the stochastic PA's bands
    plot_lstar_histograms(ens, pas, outputs)     the distribution of l_* over the seeds, one panel per point

``ens`` is the dataset of :func:`vesicle_core.analysis.noise_tables.ensemble_dataset`; ``pas`` are stochastic PA
datasets (:func:`~vesicle_core.analysis.noise_tables.stochastic_pa_dataset`). Every function returns the written
paths.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import ConfigError
from .plots import PA_STYLE, SIM_STYLE, _mpl, save_figure

__all__ = ["point_id", "point_members", "deterministic_twin", "matching_pa", "plot_lstar_noise",
           "plot_dynamics_noise", "plot_lstar_histograms"]

_SEED = re.compile(r"_n\d+$")


def point_id(case_id: str) -> str:
    """A noisy run's ensemble point: its case id without the seed (``..._kT0.0405_n3`` -> ``..._kT0.0405``)."""
    return _SEED.sub("", str(case_id))


def point_members(rows) -> dict:
    """Noisy spectra rows (``noise.py``'s analysis rows) grouped per point id, sorted by seed."""
    out = {}
    for r in rows:
        if r["kT"] > 0:
            out.setdefault(point_id(r["case_id"]), []).append(r)
    return {k: sorted(v, key=lambda r: r["noise_seed"]) for k, v in sorted(out.items())}


def _same(a, b):
    return math.isclose(float(a), float(b), rel_tol=1e-6)


def deterministic_twin(rows, r):
    """The deterministic run (kT = 0) at the same Delta, S, N and vertex count as row ``r``, or None."""
    for d in rows:
        if d["kT"] == 0 and _same(d["delta"], r["delta"]) and _same(d["S"], r["S"]) and d["N"] == r["N"] \
                and d["vertices"] == r["vertices"]:
            return d
    return None


def matching_pa(pas, r, grid=True):
    """The stochastic PA dataset of row ``r``'s (Delta, S, kT), on its grid (``grid``) or in the continuum."""
    want = int(r["N"]) if grid else 0
    for p in pas:
        a = p.attrs
        if _same(a["delta"], r["delta"]) and _same(a["S"], r["S"]) and _same(a["kT"], r["kT"]) \
                and int(a.get("grid_N", 0)) == want:
            return p
    return None


def _v(ds, name):
    return np.asarray(ds[name].values)


def plot_lstar_noise(ens, fit=None, outputs="lstar_vs_S_noise.png", *, dpi=150, measure="l_star"):
    """Fig. 4 with noise (module docstring); one colour per (Delta, kT), the room temperature's ensembles filled."""
    plt = _mpl()
    fig, ax = plt.subplots(figsize=(6.4, 4.8), constrained_layout=True)
    delta, S, kT = _v(ens, "point_delta"), _v(ens, "point_S"), _v(ens, "point_kT")
    N, nv = _v(ens, "point_N"), _v(ens, "point_vertices")
    mean, sd = _v(ens, f"point_{measure}_mean"), _v(ens, f"point_{measure}_sd")
    colours = iter(plt.rcParams["axes.prop_cycle"].by_key()["color"])
    for d in sorted(set(delta.tolist())):
        for k in sorted(set(kT[delta == d].tolist())):
            c = next(colours)
            sel = np.flatnonzero((delta == d) & (kT == k))
            # each S at its finest (N, vertices): the band is the converged ensemble where a rung was run
            best = {}
            for i in sel:
                best[S[i]] = max(best.get(S[i], (0, 0, -1)), (N[i], nv[i], i))
            idx = np.array([best[s][2] for s in sorted(best)])
            lab = f"$\\Delta$={d:g}, kT={k:g}"
            ax.plot(S[idx], mean[idx], "o-", color=c, label=f"IBM ensemble mean ({lab})", **{"lw": SIM_STYLE["lw"]})
            ax.fill_between(S[idx], mean[idx] - sd[idx], mean[idx] + sd[idx], color=c, alpha=0.2, lw=0)
            det = _v(ens, "point_det_l_star")[idx]
            if measure == "l_star" and np.isfinite(det).any():
                ax.plot(S[idx], det, "s", color=c, mfc="none", ms=7, label=f"IBM deterministic ($\\Delta$={d:g})")
            for src, mk, name in (("pa", "^", "stochastic PA, continuum"), ("gpa", "v", "stochastic PA, IBM grid")):
                m = _v(ens, f"point_{src}_{measure}_mean")[idx] if f"point_{src}_{measure}_mean" in ens else None
                if m is not None and np.isfinite(m).any():
                    ax.plot(S[idx], m, mk, color=c, ls=":", lw=1, label=f"{name} ({lab})")
    if fit is not None and "kind" in fit:
        kind = np.asarray(fit["kind"].values).astype(str)
        th = kind == "theory"
        for d in sorted(set(np.round(_v(fit, "delta")[th], 4).tolist())):
            sel = th & np.isclose(_v(fit, "delta"), d, rtol=1e-3)
            order = np.argsort(_v(fit, "S")[sel])
            ax.plot(_v(fit, "S")[sel][order], _v(fit, measure)[sel][order], color="0.4",
                    label=f"PA, deterministic ($\\Delta$={d:g})", **PA_STYLE)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("S")
    ax.set_ylabel("$l_*$ (eq. 31)" if measure == "l_star" else "$l_{peak}$")
    ax.set_title("Fig. 4 with thermal noise: ensemble mean $\\pm$ sd over seeds", fontsize=10)
    ax.legend(fontsize=7, loc="upper left")
    return save_figure(fig, outputs, dpi=dpi)


def _band(ax, t, Y, colour, label, style, log=False):
    """Mean +- sd over the first axis of Y (seeds, time); on a log axis the band is the geometric mean x/ gsd."""
    Y = np.asarray(Y, dtype=float)
    if log:
        L = np.log(np.where(Y > 0, Y, np.nan))
        m, s = np.nanmean(L, axis=0), np.nanstd(L, axis=0, ddof=1)
        mid, lo, hi = np.exp(m), np.exp(m - s), np.exp(m + s)
    else:
        mid, s = np.nanmean(Y, axis=0), np.nanstd(Y, axis=0, ddof=1)
        lo, hi = mid - s, mid + s
    ax.plot(t, mid, color=colour, label=label, **style)
    ax.fill_between(t, lo, hi, color=colour, alpha=0.2, lw=0)


def _on_grid(dss, name, t, l=None):
    rows = []
    for d in dss:
        y = d[name] if l is None else (d[name].sel(l=l) if l <= int(d["l"].max()) else None)
        rows.append(np.interp(t, np.asarray(d["time"].values, float), np.asarray(y.values, float),
                              left=np.nan, right=np.nan) if y is not None else np.full(t.size, np.nan))
    return np.array(rows)


def plot_dynamics_noise(sims, det=None, pa=None, outputs="dynamics_noise.png", *, dpi=150):
    """Fig. 3/5 with noise for one point: (a) sigma(t), (b) Delta_2(t) and Delta_l*(t), l* the ensemble's rounded
    mean l_peak; IBM seeds as a band (solid), the deterministic IBM as a line, the stochastic PA's bands (dashed)."""
    if not sims:
        raise ConfigError("plot_dynamics_noise needs at least one noisy run")
    plt = _mpl()
    fig, (ax_s, ax_d) = plt.subplots(1, 2, figsize=(10.5, 4.0), constrained_layout=True)
    t = np.asarray(sims[0]["time"].values, dtype=float)
    t = t[t >= 0]
    peaks = [float(d["l_peak"]) for d in sims if "l_peak" in d and np.isfinite(float(d["l_peak"]))]
    ls = int(round(np.mean(peaks))) if peaks else None
    _band(ax_s, t, _on_grid(sims, "sigma", t), "k", f"IBM, {len(sims)} seeds (mean $\\pm$ sd)", SIM_STYLE)
    _band(ax_d, t, _on_grid(sims, "Delta_l", t, 2), "tab:blue", "IBM $\\Delta_2$", SIM_STYLE, log=True)
    if ls is not None:
        _band(ax_d, t, _on_grid(sims, "Delta_l", t, ls), "tab:red", f"IBM $\\Delta_{{{ls}}}$", SIM_STYLE, log=True)
    if det is not None:
        td = np.asarray(det["time"].values, float)
        k = td >= 0
        ax_s.plot(td[k], np.asarray(det["sigma"].values, float)[k], color="0.3", lw=1, label="IBM deterministic")
        ax_d.plot(td[k], np.asarray(det["Delta_l"].sel(l=2).values, float)[k], color="tab:blue", lw=1, ls="-.",
                  label="IBM deterministic $\\Delta_2$")
    if pa is not None:
        tp = np.asarray(pa["time"].values, float)
        keep = tp <= t.max()
        n = pa.sizes["seed"]
        lab = "stochastic PA" + (" (grid)" if int(pa.attrs.get("grid_N", 0)) else "")
        _band(ax_s, tp[keep], np.asarray(pa["sigma"].values)[:, keep], "0.45", f"{lab}, {n} seeds", PA_STYLE)
        _band(ax_d, tp[keep], np.asarray(pa["Delta_2"].values)[:, keep], "tab:cyan", f"{lab} $\\Delta_2$", PA_STYLE,
              log=True)
    ts = [float(d["t_star"]) for d in sims]
    for ax in (ax_s, ax_d):
        ax.axvspan(min(ts), max(ts), color="0.85", alpha=0.5, lw=0)
        ax.set_xlabel("$\\dot\\gamma (t - t_0)$")
        ax.legend(fontsize=7)
    ax_s.set_ylabel("$\\sigma$ [$\\kappa/R^2$]")
    ax_d.set_yscale("log")
    ax_d.set_ylabel("$\\Delta_l$")
    a = sims[0].attrs
    fig.suptitle(f"$\\Delta$ = {float(a.get('mesh_target_delta', a.get('delta', math.nan))):.3g}, "
                 f"S = {float(a.get('S', math.nan)):g}, N = {a.get('N', '?')}, kT = {float(a.get('kT', 0)):g}: "
                 f"bands mean $\\pm$ sd over seeds (grey: range of $t_*$)", fontsize=10)
    return save_figure(fig, outputs, dpi=dpi)


def plot_lstar_histograms(ens, pas=(), outputs="lstar_hist.png", *, dpi=150):
    """One panel per point: the IBM seeds' l_* (filled), the stochastic PA's on the grid and in the continuum
    (steps), the deterministic IBM (vertical line)."""
    plt = _mpl()
    n = ens.sizes["point"]
    cols = min(n, 4)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), constrained_layout=True, squeeze=False)
    seeds = _v(ens, "point_l_star_seed")
    for i, ax in enumerate(axes.ravel()):
        if i >= n:
            ax.axis("off")
            continue
        r = {k: float(_v(ens, f"point_{k}")[i]) for k in ("delta", "S", "kT")}
        r["N"] = int(_v(ens, "point_N")[i])
        vals = seeds[i][np.isfinite(seeds[i])]
        pa_g, pa_c = matching_pa(pas, r, grid=True), matching_pa(pas, r, grid=False)
        allv = [vals] + [np.asarray(p["l_star"].values, float) for p in (pa_g, pa_c) if p is not None]
        lo, hi = min(v.min() for v in allv), max(v.max() for v in allv)
        bins = np.linspace(lo - 0.5, hi + 0.5, 13)
        ax.hist(vals, bins=bins, density=True, color="tab:blue", alpha=0.6, label=f"IBM ({vals.size} seeds)")
        for p, c, name in ((pa_g, "tab:red", "SPA grid"), (pa_c, "0.3", "SPA continuum")):
            if p is not None:
                ax.hist(np.asarray(p["l_star"].values, float), bins=bins, density=True, histtype="step", color=c,
                        label=f"{name} ({p.sizes['seed']})")
        det = float(_v(ens, "point_det_l_star")[i])
        if math.isfinite(det):
            ax.axvline(det, color="k", ls="--", lw=1, label="IBM deterministic")
        ax.set_title(f"$\\Delta$={r['delta']:g} S={r['S']:g} N={r['N']} kT={r['kT']:g}", fontsize=8)
        ax.set_xlabel("$l_*$", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6)
    fig.suptitle("Distribution of $l_*$ (eq. 31) over the noise seeds", fontsize=10)
    return save_figure(fig, outputs, dpi=dpi)
