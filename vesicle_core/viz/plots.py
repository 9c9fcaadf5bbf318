"""Figures of the reference paper from the package's datasets (matplotlib, Agg backend: no display needed).

    plot_dynamics(spectra, theory, outputs)   Fig. 3/5 style: sigma(t), Delta_2(t), Delta_{l_*}(t), IBM against
                                              PA, the three stages and t_* marked
    plot_lstar(fit, outputs)                  Fig. 4: l_* against S (log-log), simulation and PA, fitted
                                              exponents with intervals, S^(1/3) guide
    plot_wrinkles(spectra, outputs)           Fig. 8 style: A_p(theta, phi) maps at chosen times (when the spectra
                                              hold ``A_p_map``), A_p-bar(t), Delta~_l(t) heat map

Inputs are xarray Datasets or paths of the package's netCDF files (layouts in ``datasets.py``, ``theory.py``,
``fits.py``). ``outputs`` is one path or a list; the format follows each suffix (.png, .svg, .pdf), so one call
writes the PNG and its vector copy. Every function returns the list of written paths. Times are gamma_dot (t - t0)
(0 = the flow reversal); tensions are in kappa/R^2.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import ConfigError, require

__all__ = ["plot_dynamics", "plot_lstar", "plot_wrinkles", "save_figure", "FORMATS"]

FORMATS = ("png", "svg", "pdf")
SIM_STYLE = {"ls": "-", "lw": 1.6}
PA_STYLE = {"ls": "--", "lw": 1.4}
STAGE_COLOURS = ("#fde0c5", "#d5e8d4", "#dae8fc")


def _mpl():
    matplotlib = require("matplotlib", "viz", "plotting")

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "cairo"):
        try:
            matplotlib.use("Agg")
        except Exception:  # pragma: no cover - a backend was already fixed by the caller
            pass
    import matplotlib.pyplot as plt

    return plt


def _load(obj, what):
    import xarray as xr

    if obj is None or isinstance(obj, xr.Dataset):
        return obj
    path = Path(obj)
    if not path.is_file():
        raise ConfigError(f"{what}: {path} does not exist")
    with xr.open_dataset(path, engine="netcdf4") as ds:
        return ds.load()


def _outputs(outputs):
    if isinstance(outputs, (str, Path)):
        outputs = [outputs]
    outs = [Path(o) for o in outputs]
    if not outs:
        raise ConfigError("no output file given")
    for o in outs:
        fmt = o.suffix.lower().lstrip(".")
        if fmt not in FORMATS:
            raise ConfigError(f"output {o}: unknown figure format {fmt!r}; use one of {', '.join(FORMATS)}")
    return outs


def save_figure(fig, outputs, dpi=150):
    """Write ``fig`` to every path in ``outputs`` (format from the suffix) and close it."""
    plt = _mpl()
    written = []
    try:
        for o in _outputs(outputs):
            o.parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(o, dpi=dpi, bbox_inches="tight")
            written.append(o)
    finally:
        plt.close(fig)
    return written


def _attr(ds, name, default=math.nan):
    v = ds.attrs.get(name, default)
    try:
        return float(np.asarray(v).ravel()[0])
    except (TypeError, ValueError, IndexError):
        return default


def _scalar(ds, name):
    if ds is None or name not in ds.variables:
        return math.nan
    try:
        return float(ds[name].values)
    except (TypeError, ValueError):
        return math.nan


def _case_label(ds):
    d, S, chi = _attr(ds, "mesh_target_delta", _attr(ds, "delta")), _attr(ds, "S"), _attr(ds, "chi")
    parts = []
    if math.isfinite(d):
        parts.append(f"$\\Delta$ = {d:.4g}")
    if math.isfinite(S):
        parts.append(f"S = {S:.5g}")
    if math.isfinite(chi):
        parts.append(f"$\\chi$ = {chi:.4g}")
    n = ds.attrs.get("N")
    if n is not None:
        parts.append(f"N = {int(np.asarray(n).ravel()[0])}")
    return ", ".join(parts)


def _delta_l_series(ds, l):
    """Delta_l(t) of one degree (NaN if the dataset does not resolve it)."""
    if l is None or "Delta_l" not in ds or l > int(ds["l"].max()) or l < 0:
        return None
    return np.asarray(ds["Delta_l"].sel(l=l).values, dtype=float)


def _round_l(v):
    return int(round(v)) if math.isfinite(v) and v >= 2 else None


def _stages(t, sigma, noisy):
    """Stage boundaries from vesicle_core.analysis.fits (None when sigma(t) shows no clean stages)."""
    from ..analysis.fits import detect_tension_stages

    keep = (t > 0) & np.isfinite(sigma)
    if keep.sum() < 8:
        return None
    kw = {"smooth": 3, "rms_tol": 0.05, "plateau_drop": 0.05} if noisy else {}
    try:
        return detect_tension_stages(t[keep], sigma[keep], **kw)
    except (ConfigError, ValueError):
        return None


def _shade_stages(ax, st, x0, x1, label=True):
    """Shade stages I-III (clipped to the visible range [x0, x1])."""
    if st is None:
        return
    spans = [(0.0, st.t_stage1_end, "I"), (st.t_stage2_start, st.t_stage2_end, "II")]
    if math.isfinite(st.t_recovery):
        spans.append((st.t_recovery, x1, "III"))
    for (a, b, name), col in zip(spans, STAGE_COLOURS, strict=False):  # stage III is optional
        if not (math.isfinite(a) and math.isfinite(b)):
            continue
        a, b = max(a, x0), min(b, x1)
        if b <= a:
            continue
        ax.axvspan(a, b, color=col, alpha=0.6, lw=0, zorder=0)
        if label:
            ax.text(0.5 * (a + b), 0.97, name, transform=ax.get_xaxis_transform(), ha="center", va="top",
                    fontsize=9, color="0.3")


def _label_dynamics_axes(ax_s, ax_d):
    """Axes, labels and legends of :func:`plot_dynamics`' two panels: (a) sigma(t), (b) Delta_l(t) on a log scale."""
    ax_s.axhline(0.0, color="0.6", lw=0.8)
    ax_s.set_xlabel(r"$\dot\gamma (t - t_0)$")
    ax_s.set_ylabel(r"$\sigma$  [$\kappa/R^2$]")
    ax_s.set_title("(a) global surface tension", fontsize=10)
    ax_s.legend(fontsize=8, loc="best")
    ax_d.set_yscale("log")
    ax_d.set_xlabel(r"$\dot\gamma (t - t_0)$")
    ax_d.set_ylabel(r"$\Delta_l = \sum_m |u_{l,m}|^2$")
    ax_d.set_title(r"(b) $\Delta_2$ and $\Delta_{l_*}$", fontsize=10)
    if ax_d.lines:
        ax_d.legend(fontsize=8, loc="best")


def plot_dynamics(spectra, theory=None, outputs="dynamics.png", *, title=None, dpi=150, t_min=0.0, t_max=None):
    """Fig. 3/5 style: (a) sigma(t); (b) Delta_2(t) and Delta_{l_*}(t); simulation (solid) and PA (dashed).

    spectra: simulation spectra (or None to plot the PA alone); theory: PA dataset (or None). The l_* of
    Delta_{l_*} is each dataset's own dominant mode at t_* (``l_peak``; the rounded eq. (31) value if absent);
    the legend also gives eq. (31). Stages come from the simulation's sigma(t) when it shows them, else from the
    PA's. Only t >= t_min is shown (default: from the reversal).
    """
    plt = _mpl()
    sim = _load(spectra, "spectra")
    pa = _load(theory, "theory")
    if sim is None and pa is None:
        raise ConfigError("plot_dynamics needs simulation spectra, a PA dataset, or both")
    fig, (ax_s, ax_d) = plt.subplots(1, 2, figsize=(10.5, 4.0), constrained_layout=True)
    series = []
    for ds, name, style in ((sim, "IBM", SIM_STYLE), (pa, "PA", PA_STYLE)):
        if ds is None:
            continue
        t = np.asarray(ds["time"].values, dtype=float)
        keep = t >= t_min
        if t_max is not None:
            keep &= t <= t_max
        if not keep.any():
            raise ConfigError(f"{name}: no samples in the time range [{t_min}, {t_max}]")
        sig = np.asarray(ds["sigma"].values, dtype=float)
        # Delta_{l_*} of Figs. 3/5 is the dominant mode at t_* (Sec. V.A: Delta_{l_*}(t_*) >= Delta_l(t_*)), i.e.
        # l_peak; eq. (31) gives a non-integer l_* whose rounding can land on a mode the symmetry keeps at zero
        ls = _round_l(_scalar(ds, "l_peak")) or _round_l(_scalar(ds, "l_star"))
        series.append((ds, name, style, t, keep, sig, ls))
    stages = None
    for _ds, name, _style, t, _keep, sig, _ls in series:
        stages = _stages(t, sig, noisy=(name == "IBM"))
        if stages is not None:
            stage_src = name
            break
    colours = {"sigma": "k", 2: "tab:blue", "lstar": "tab:red"}
    curves_d = []
    for ds, name, style, t, keep, sig, ls in series:
        ax_s.plot(t[keep], sig[keep], color=colours["sigma"] if name == "IBM" else "0.45", label=name, **style)
        d2 = _delta_l_series(ds, 2)
        if d2 is not None:
            ax_d.plot(t[keep], d2[keep], color=colours[2], label=f"{name} $\\Delta_2$", **style)
            curves_d.append((t[keep], d2[keep]))
        dl = _delta_l_series(ds, ls)
        if dl is not None:
            l31 = _scalar(ds, "l_star")
            ax_d.plot(t[keep], dl[keep], color=colours["lstar"],
                      label=f"{name} $\\Delta_{{{ls}}}$ (eq. 31: $l_*$ = {l31:.1f})", **style)
            curves_d.append((t[keep], dl[keep]))
        ts = _scalar(ds, "t_star")
        if math.isfinite(ts):
            for ax in (ax_s, ax_d):
                ax.axvline(ts, color="k" if name == "IBM" else "0.5", ls=":", lw=1)
    _label_dynamics_axes(ax_s, ax_d)
    # x range: the simulation's when there is one (the PA runs on past the end of a short run)
    ref = [s for s in series if s[1] == "IBM"] or series
    x0 = max(t_min, min(float(s[3][s[4]].min()) for s in ref))
    x1 = max(float(s[3][s[4]].max()) for s in ref)
    x1 = x1 if x1 > x0 else x0 + 1.0
    for ax in (ax_s, ax_d):
        ax.set_xlim(x0, x1)
        _shade_stages(ax, stages, x0, x1)
    # y range of (b): down to 1e-8 of the largest value shown (the PA's high modes decay by many decades)
    shown = np.concatenate([y[(x >= x0) & (x <= x1)] for x, y in curves_d] or [np.array([])])
    shown = shown[np.isfinite(shown) & (shown > 0)]
    if shown.size:
        hi = float(shown.max())
        ax_d.set_ylim(max(float(shown.min()), hi * 1e-8) / 2.0, hi * 2.0)
    if title is None:
        title = _case_label(sim if sim is not None else pa)
        if stages is not None:
            title += f"   (stages from the {stage_src} tension)"
    fig.suptitle(title, fontsize=11)
    return save_figure(fig, outputs, dpi=dpi)


def _group_key(delta):
    return float(f"{float(delta):.4g}")


def _source_name(kind, kT=0.0):
    """IBM or PA, with the temperature of a noisy group."""
    return ("IBM" if kind == "simulation" else "PA") + (f" (kT = {kT:g})" if kT > 0 else "")


def _drawn_groups(ds, keys) -> set:
    """The simulation groups Fig. 4 draws per Delta: the one that takes each S at its finest rung where the sweep has
    several resolutions (group_N < 0, sweep_fits.FINEST), else the finest resolution's."""
    if "group" not in ds.dims or "group_N" not in ds.variables:
        return set()
    gk = np.asarray(ds["group_kind"].values).astype(str)
    gN = np.asarray(ds["group_N"].values, dtype=int)
    gd = [_group_key(d) for d in np.asarray(ds["group_delta"].values, dtype=float)]
    out = set()
    for k in keys:
        sim = [i for i in range(len(gk)) if gk[i] == "simulation" and gd[i] == k]
        mixed = [i for i in sim if gN[i] < 0]
        out.update(mixed or [i for i in sim if gN[i] == max((gN[j] for j in sim), default=0)])
    return out


def _draw_ensembles(ax, ds, measure, colour, drawn):
    """Mean +- sd over the noise seeds at each S of an ensemble (fit's ``point`` dimension, > 1 seed)."""
    if "point" not in ds.dims or f"point_{measure}_mean" not in ds.variables:
        return
    n = np.asarray(ds["point_n_seeds"].values, dtype=int)
    g = np.asarray(ds["point_group"].values, dtype=int)
    first = True
    for i in np.flatnonzero(n > 1):
        if int(g[i]) not in drawn:
            continue
        k = _group_key(float(ds["group_delta"].values[g[i]]))
        ax.errorbar(float(ds["point_S"].values[i]), float(ds[f"point_{measure}_mean"].values[i]),
                    yerr=float(ds[f"point_{measure}_sd"].values[i]), fmt="D", ms=5, capsize=3, color=colour[k],
                    mfc="white", label=f"IBM ensemble mean +- sd ({n[i]} seeds)" if first else None)
        first = False


def _finest_cases(ds, kind, delta, S, keys):
    """Which cases Fig. 4 shows (the PA's, and each (Delta, S)'s simulations at its finest (N, vertices)) and, per
    Delta, the grids N of the simulations shown."""
    n = len(S)
    N = np.asarray(ds["N"].values, dtype=int) if "N" in ds.variables else np.zeros(n, dtype=int)
    nv = np.asarray(ds["vertices"].values, dtype=int) if "vertices" in ds.variables else np.zeros(n, dtype=int)
    sim = kind == "simulation"
    finest = {}
    for i in np.flatnonzero(sim):
        key = (_group_key(delta[i]), S[i])
        finest[key] = max(finest.get(key, (0, 0)), (int(N[i]), int(nv[i])))
    shown = ~sim | np.array([(int(N[i]), int(nv[i])) == finest.get((_group_key(delta[i]), S[i])) for i in range(n)])
    grids = {k: sorted({int(N[i]) for i in np.flatnonzero(sim & shown) if _group_key(delta[i]) == k}) for k in keys}
    return shown, grids


def plot_lstar(fit, outputs="lstar_vs_S.png", *, measure="l_star", dpi=150, guide=True):
    """Fig. 4: l_* (``measure`` = "l_star", eq. 31, or "l_peak", the dominant mode) against S on log-log axes.

    ``fit`` is the dataset of ``vesicle fit`` (vesicle_core.analysis.sweep_fits.sweep_fit_dataset): per-case points
    on the ``case`` dimension and per-group power laws on ``group``. Groups with fewer than three points have NaN
    exponents and are drawn without a line. Simulations are drawn at each (Delta, S)'s finest grid only (a
    resolution study's coarser rungs, seeds and variations would otherwise pile up at the same S), with the N in the
    legend; where the points' finest grids differ between S, the line is the fit over each S at its finest rung.
    An ensemble (several noise seeds at one S) adds its mean +- sd over the seeds.
    """
    plt = _mpl()
    if measure not in ("l_star", "l_peak"):
        raise ConfigError(f"measure must be 'l_star' or 'l_peak', got {measure!r}")
    ds = _load(fit, "fit")
    for v in ("kind", "delta", "S", measure):
        if v not in ds.variables:
            raise ConfigError(f"fit dataset lacks the variable {v!r} (is it the output of 'vesicle fit'?)")
    kind = np.asarray(ds["kind"].values).astype(str)
    delta = np.asarray(ds["delta"].values, dtype=float)
    S = np.asarray(ds["S"].values, dtype=float)
    y = np.asarray(ds[measure].values, dtype=float)
    keys = sorted({_group_key(d) for d in delta})
    kT = np.asarray(ds["kT"].values, dtype=float) if "kT" in ds.variables else np.zeros(len(S))
    shown, grids = _finest_cases(ds, kind, delta, S, keys)
    drawn = _drawn_groups(ds, keys)
    cmap = plt.get_cmap("tab10")
    colour = {k: cmap(i % 10) for i, k in enumerate(keys)}
    fig, ax = plt.subplots(figsize=(6.0, 4.6), constrained_layout=True)
    ok = np.isfinite(S) & np.isfinite(y) & (S > 0) & (y > 0) & shown
    for k in keys:
        for knd, marker, face, name in (("simulation", "o", None, "IBM"), ("theory", "s", "none", "PA")):
            sel = ok & (kind == knd) & np.array([_group_key(d) == k for d in delta])
            grid = (f", N = {'/'.join(map(str, grids[k]))}" if knd == "simulation" and grids[k] and grids[k][-1] > 0
                    else "")
            # noisy runs (an ensemble's members) as small faded points beside the deterministic ones
            for hot in (False, True):
                part = sel & ((kT > 0) == hot)
                if not part.any():
                    continue
                note = f", kT = {kT[part].max():g} (each seed)" if hot else ""
                ax.plot(S[part], y[part], marker=marker, ls="none", ms=4 if hot else 7, color=colour[k],
                        alpha=0.45 if hot else 1.0, mfc=colour[k] if face is None else "none",
                        label=f"{name}, $\\Delta$ = {k:g}{grid}{note}")
    _draw_ensembles(ax, ds, measure, colour, drawn)
    if "group" in ds.dims:
        gk = np.asarray(ds["group_kind"].values).astype(str)
        gd = np.asarray(ds["group_delta"].values, dtype=float)
        for i in range(ds.sizes["group"]):
            b = float(ds[f"{measure}_exponent"].values[i])
            if not math.isfinite(b):
                continue
            lo = float(ds[f"{measure}_ci_low"].values[i])
            hi = float(ds[f"{measure}_ci_high"].values[i])
            c = float(ds[f"{measure}_prefactor"].values[i])
            k = _group_key(gd[i])
            if gk[i] == "simulation" and "group_N" in ds.variables and i not in drawn:
                continue
            sel = ok & (kind == gk[i]) & np.array([_group_key(d) == k for d in delta])
            if sel.sum() < 2:
                continue
            xs = np.geomspace(S[sel].min(), S[sel].max(), 50)
            name = _source_name(gk[i], float(ds["group_kT"].values[i]) if "group_kT" in ds.variables else 0.0)
            conf = float(ds.attrs.get("confidence", 0.95))
            ax.plot(xs, c * xs**b, color=colour.get(k, "k"), ls="-" if gk[i] == "simulation" else "--", lw=1.2,
                    label=f"{name} fit: $S^{{{b:.3f}}}$, {conf:.0%} CI [{lo:.3f}, {hi:.3f}]")
    if guide and ok.any():
        xs = np.geomspace(S[ok].min(), S[ok].max(), 50)
        x0 = math.exp(np.mean(np.log(S[ok])))
        y0 = math.exp(np.mean(np.log(y[ok])))
        ax.plot(xs, y0 * (xs / x0) ** (1.0 / 3.0), color="0.5", ls=":", lw=1.5, label=r"$S^{1/3}$ guide")
    _lstar_axes(ax, S[ok], measure)
    return save_figure(fig, outputs, dpi=dpi)


def _lstar_axes(ax, S, measure):
    """Fig. 4's log-log axes, labels and legend; ``S`` the flow strengths drawn."""
    ax.set_xscale("log")
    ax.set_yscale("log")
    if S.size and np.ptp(np.log(S)) < 1e-9:  # one S (an ensemble): a log axis of zero width shows nothing
        ax.set_xlim(S[0] / 2.0, S[0] * 2.0)
    ax.set_xlabel("flow strength S")
    ax.set_ylabel(r"$l_*$ (eq. 31)" if measure == "l_star" else r"dominant mode $l$ at $t_*$")
    ax.set_title(r"characteristic wrinkle mode against flow strength", fontsize=10)
    if ax.lines:
        ax.legend(fontsize=7.5, loc="upper left")
    ax.grid(True, which="both", alpha=0.25)


def _nearest_indices(t, times):
    out = []
    for x in times:
        i = int(np.argmin(np.abs(t - float(x))))
        if i not in out:
            out.append(i)
    return out


def plot_wrinkles(spectra, outputs="wrinkles.png", *, times=None, dpi=150, l_min=2):
    """Fig. 8 style: A_p(theta, phi) maps at ``times`` (nearest frames; default t_*/2, t_*, 3 t_*/2) when
    the spectra hold ``A_p_map``; A_p-bar(t); Delta~_l(t) for l >= l_min as a heat map with logarithmic colours."""
    plt = _mpl()
    from matplotlib.colors import LogNorm, TwoSlopeNorm

    ds = _load(spectra, "spectra")
    for v in ("A_p_bar", "Delta_tilde_l"):
        if v not in ds.variables:
            raise ConfigError(f"spectra lack {v!r}: plot_wrinkles needs the output of 'vesicle decompose'")
    t = np.asarray(ds["time"].values, dtype=float)
    has_maps = "A_p_map" in ds.variables
    if times is None:  # around the wrinkling: t_*/2, t_*, 3 t_*/2 (t0, middle and end if there is no t_*)
        ts = _scalar(ds, "t_star")
        times = [0.5 * ts, ts, 1.5 * ts] if math.isfinite(ts) and ts > 0 else [0.0, 0.5 * float(t.max()),
                                                                                  float(t.max())]
    idx = _nearest_indices(t, times) if has_maps else []
    if has_maps:
        fig = plt.figure(figsize=(max(10.0, 3.6 * len(idx)), 7.4), constrained_layout=True)
        gs = fig.add_gridspec(2, max(len(idx), 2) * 2)
        n = len(idx)
        w = (max(n, 2) * 2) // n
        map_axes = [fig.add_subplot(gs[0, i * w:(i + 1) * w]) for i in range(n)]
        half = max(n, 2)
        ax_a = fig.add_subplot(gs[1, :half])
        ax_h = fig.add_subplot(gs[1, half:])
        maps = np.asarray(ds["A_p_map"].values, dtype=float)
        vmax = float(np.nanmax(np.abs(maps[idx]))) if idx else 1.0
        vmax = vmax if vmax > 0 and math.isfinite(vmax) else 1.0
        norm = TwoSlopeNorm(vcenter=0.0, vmin=-vmax, vmax=vmax)
        th = np.asarray(ds["theta"].values, dtype=float)
        ph = np.asarray(ds["phi"].values, dtype=float)
        im = None
        for ax, i in zip(map_axes, idx, strict=True):
            im = ax.pcolormesh(ph, th, maps[i], cmap="RdBu_r", norm=norm, shading="auto", rasterized=True)
            ax.set_title(rf"$A_p(\theta,\phi)$ at $\dot\gamma (t - t_0)$ = {t[i]:.3g}", fontsize=9)
            ax.set_xlabel(r"$\phi$")
            ax.set_ylabel(r"$\theta$")
            ax.set_xticks([-math.pi, -math.pi / 2, 0, math.pi / 2, math.pi], [r"$-\pi$", r"$-\pi/2$", "0",
                                                                               r"$\pi/2$", r"$\pi$"])
            ax.set_yticks([0, math.pi / 2, math.pi], ["0", r"$\pi/2$", r"$\pi$"])
        if im is not None:
            fig.colorbar(im, ax=map_axes, label=r"$A_p$  [$R$]", shrink=0.9)
    else:
        fig, (ax_a, ax_h) = plt.subplots(1, 2, figsize=(10.5, 4.0), constrained_layout=True)
    ax_a.plot(t, np.asarray(ds["A_p_bar"].values, dtype=float), color="tab:purple", lw=1.6)
    ax_a.set_xlabel(r"$\dot\gamma (t - t_0)$")
    ax_a.set_ylabel(r"$\bar A_p$  [$R^2$]")
    ax_a.set_title(r"mean square wrinkle amplitude $\bar A_p(t)$", fontsize=10)
    ts = _scalar(ds, "t_star")
    if math.isfinite(ts):
        ax_a.axvline(ts, color="k", ls=":", lw=1, label=r"$t_*$")
        ax_a.legend(fontsize=8)
    ax_a.axvline(0.0, color="0.6", lw=0.8)
    D = np.asarray(ds["Delta_tilde_l"].values, dtype=float)
    ls = np.asarray(ds["l"].values, dtype=int)
    keep = ls >= l_min
    Dk = D[:, keep]
    pos = Dk[np.isfinite(Dk) & (Dk > 0)]
    if pos.size:
        vmax = float(pos.max())
        vmin = max(float(pos.min()), vmax * 1e-8)
        Dplot = np.where(np.isfinite(Dk) & (Dk > 0), Dk, np.nan)
        hm = ax_h.pcolormesh(t, ls[keep], Dplot.T, norm=LogNorm(vmin=vmin, vmax=vmax), cmap="viridis",
                             shading="auto", rasterized=True)
        fig.colorbar(hm, ax=ax_h, label=r"$\tilde\Delta_l = \sum_m |\tilde u_{l,m}|^2$")
    ax_h.set_xlabel(r"$\dot\gamma (t - t_0)$")
    ax_h.set_ylabel("degree $l$")
    ax_h.set_title(r"excess area per mode $\tilde\Delta_l(t)$, eq. (32)", fontsize=10)
    if math.isfinite(ts):
        ax_h.axvline(ts, color="w", ls=":", lw=1)
    fig.suptitle(_case_label(ds), fontsize=11)
    return save_figure(fig, outputs, dpi=dpi)
