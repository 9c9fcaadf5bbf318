"""Validation study (issue 6), the numbers: everything the validation report states, read from the produced files.

``collect(manifest)`` opens the manifest's files and returns the report's data: per case l_* (simulation, this
project's PA, the paper's PA and IBM values, Figs. 3, 4, 5), stage-1 growth, stage-2 local decay exponents,
area/volume drift, time step, steps and wall time per run; the fitted exponents (fits.nc); the periodic-box test
(Table I, box.py); the single-mode relaxation of each ladder grid, the PA's exponent against its mode cutoff and the
PA on each run's grid. ``ladder_summary`` extrapolates the resolution ladder. Nothing here is tuned per case: every
number is read from the files; report.py turns them into Markdown through the templates.

Manifest (YAML/dict)::

    title: str
    resolution_note: str            # e.g. "N = 64, 2562-vertex quasi-uniform mesh"
    cases:   [{case_id, group, trajectory, spectra, theory}]   # group: "fine" or "coarse"
    fits:    {fine: fit.nc, coarse: fit.nc}
    box:     {small: trajectory.nc, large: trajectory.nc}       # optional
    figures: [{path, caption}]                                  # paths relative to the report
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from ..model.resolution import DEFAULT_KERNEL
from .box import box_comparison, box_tension

#: published values (Figs. 3, 4, 5; Sec. V.A)
PAPER_L_STAR = {  # (Delta, S) -> (PA, IBM)
    (0.116, 553.0): (14, 15),
    (0.116, 2224.0): (25, 28),
    (0.997, 237.0): (10, 12),
    (0.997, 947.0): (17, 24),
}
PAPER_EXPONENT_IBM = 0.3923
PAPER_EXPONENT_PA = 0.372
TURITSYN_EXPONENT = 1.0 / 3.0
PAPER_DECAY = {553.0: 0.7439, 2224.0: 0.8108}
PAPER_GRID = (512, 5.0)  # the paper's fluid grid: 512^3 nodes (Sec. V), box 2.5 diameters = 5 R (Table I)
#: Table I's largest shape difference, printed as 1.3e-3: a box shape difference up to this is "within" the paper's
PAPER_BOX_SHAPE = 1.34e-3


def _paper_lstar(delta, S):
    for (d, s), v in PAPER_L_STAR.items():
        if abs(d - delta) < 0.02 and abs(s - S) / s < 0.02:
            return v
    return None


# --------------------------------------------------------------------------- per case
def stage1_growth(spectra, l_min=6) -> float:
    """max over l >= l_min of log10(Delta_l(t_*) / Delta_l(0)): decades of growth during stage 1."""
    D = spectra["Delta_l"]
    ts = float(spectra["t_star"])
    if not math.isfinite(ts):
        return math.nan
    d0 = D.sel(time=0.0, method="nearest").values[l_min:]
    d1 = D.sel(time=ts, method="nearest").values[l_min:]
    ok = (d0 > 0) & (d1 > 0)
    return float(np.max(np.log10(d1[ok] / d0[ok]))) if ok.any() else math.nan


def _run_row(case, traj, spec, theo):
    from ..data.case_ids import parse_case_id

    delta_nominal = float(theo.attrs.get("delta", traj.attrs.get("delta")))
    S = float(theo.attrs.get("S", traj.attrs.get("S")))
    paper = _paper_lstar(delta_nominal, S)
    N = int(traj.attrs.get("N", -1))
    L = float(traj.attrs.get("L", math.nan))
    return {
        "case_id": case["case_id"], "group": case.get("group", "fine"), "delta": delta_nominal,
        "tag": (parse_case_id(case["case_id"]) or {}).get("tag"),
        "delta_mesh": float(traj.attrs.get("delta", math.nan)), "S": S, "chi": float(traj.attrs.get("chi", math.nan)),
        "N": N, "L": L, "h": L / N if N > 0 else math.nan, "vertices": int(traj.sizes["n_node"]),
        "family": str(traj.attrs.get("mesh_family", "?")), "kernel": str(traj.attrs.get("kernel", DEFAULT_KERNEL)),
        "seed_spectrum": str(traj.attrs.get("seed_spectrum", "mesh")),
        "seed_scale": float(traj.attrs.get("seed_scale", 1.0)),
        "sim_l_star": float(spec["l_star"]), "sim_l_peak": float(spec.get("l_peak", math.nan)),
        "pa_l_star": float(theo["l_star"]), "pa_l_peak": float(theo.get("l_peak", math.nan)),
        "paper_pa": paper[0] if paper else None, "paper_ibm": paper[1] if paper else None,
        "sim_t_star": float(spec["t_star"]), "pa_t_star": float(theo["t_star"]),
        "growth_decades": stage1_growth(spec),
        "max_area_drift": float(np.abs(traj["area_drift"].values).max()),
        "max_volume_drift": float(np.abs(traj["volume_drift"].values).max()),
        "dt_gamma": float(traj.attrs.get("dt_gamma", math.nan)), "steps": int(traj.attrs.get("steps", -1)),
        **_wall(traj.attrs),
        "scheme": str(traj.attrs.get("scheme", "?")),
        "defect_ratio": float(spec.get("defect_amplitude_ratio", math.nan)),
        "sim_tension_reversal": box_tension(traj) if "tension" in traj else math.nan,
        "pa_stretch_tension": pa_stretch_tension(S),
    }


def _wall(attrs) -> dict:
    """The run's wall time over all its calls; a run resumed from a checkpoint that predates that record counts
    its last call only (``wall_partial``)."""
    total = float(attrs.get("wall_time_s", math.nan))
    if math.isfinite(total):
        return {"wall_s": total, "wall_partial": False}
    return {"wall_s": float(attrs.get("wall_time_s_last_call", math.nan)),
            "wall_partial": bool(int(attrs.get("resumed", 0)))}


def pa_stretch_tension(S) -> float:
    """The PA's tension of the stationary stretched state, (S - Gamma_2) / A_2 (eq. 12 with u_{2,+-2} = 1)."""
    from ..model.modes import a_l, gamma_l

    return float((S - gamma_l(2)) / a_l(2))


def collect(manifest) -> dict:
    """The report's data from the manifest's files: {rows, fits, box, relaxation, cutoff, pa_local_decay,
    damped_pa}; the side studies (relaxation, cutoff, damped_pa) can be switched off in the manifest."""
    import xarray as xr

    rows = []
    pa_local = {}  # ("PA", S) -> local_decay of the PA
    for case in manifest["cases"]:
        with xr.open_dataset(case["trajectory"]) as traj, xr.open_dataset(case["spectra"]) as spec, \
                xr.open_dataset(case["theory"]) as theo:
            rows.append(_run_row(case, traj.load(), spec.load(), theo.load()))
            r = rows[-1]
            if paper_decay(r["S"]) is not None and r["delta"] < 0.5:
                if ("PA", r["S"]) not in pa_local:
                    pa_local[("PA", r["S"])] = local_decay(theo, "theory", paper_decay(r["S"]))
                r["local_decay"] = local_decay(spec, "simulation", paper_decay(r["S"]))
    fits = {}
    for group, path in (manifest.get("fits") or {}).items():
        with xr.open_dataset(path) as f:
            fits[group] = f.load()
    box = None
    if manifest.get("box"):
        with xr.open_dataset(manifest["box"]["small"]) as a, xr.open_dataset(manifest["box"]["large"]) as b:
            box = box_comparison(a.load(), b.load())
        small = [r for r in rows if r["group"] == "box" and abs(r["L"] - box["L_small"]) < 1e-9]
        box["tension_pa"] = small[0]["pa_stretch_tension"] if small else math.nan
    data = {"rows": rows, "fits": fits, "box": box, "relaxation": None, "cutoff": None, "pa_local_decay": pa_local}
    ladder = ladder_rows(rows)
    if ladder and manifest.get("relaxation", True):
        data["relaxation"] = relaxation_table(sorted({(r["N"], r["vertices"], r["L"]) for r in ladder}))
    if manifest.get("cutoff", True) and fits.get("fine") is not None:
        data["cutoff"] = cutoff_table(fits["fine"])
    if ladder and manifest.get("damped_pa", True):
        data["damped_pa"] = damped_pa_table([r for r in rows if r["group"] in ("ladder", "fine", "seed",
                                                                               "variation")])
        N, L = PAPER_GRID
        paper_grid = [{**r, "N": N, "h": L / N, "kernel": DEFAULT_KERNEL} for r in rows if r["group"] == "fine"]
        data["damped_pa"].update(damped_pa_table(paper_grid))
    return data


def paper_decay(S):
    return next((v for k, v in PAPER_DECAY.items() if abs(k - S) / k < 0.02), None)


def local_decay(ds, kind="theory", paper=None) -> dict:
    """How far a stage-2 tension is from one power law: the local exponent a(t) = -d ln|sigma|/d ln t
    (fits.local_decay_exponent) on the dataset's own samples (raw, as the fit uses them), inside the stage-2
    window that the fitted exponent uses (the rule and tolerances of sweep_fits.case_decay for ``kind`` 'theory' or
    'simulation'), and from the end of stage 1 to that window's end. ``paper``: the gamma_dot t at which a(t)
    first equals it there (None if it never does). {} when there is no clean stage 2."""
    from ..analysis.fits import detect_tension_stages, local_decay_exponent

    t = np.asarray(ds["time"].values, dtype=float)
    sig = np.asarray(ds["sigma"].values, dtype=float)
    keep = t > 0
    t, sig = t[keep], sig[keep]
    try:
        st = detect_tension_stages(t, sig, smooth=1 if kind == "theory" else 3,
                                   rms_tol=0.01 if kind == "theory" else 0.05)
    except Exception:  # no clean stage 2: nothing to say
        return {}
    lo, hi = st.i_stage2
    i1 = min(int(np.searchsorted(t, st.t_stage1_end)), lo)
    a = local_decay_exponent(t[i1:hi], sig[i1:hi])
    w = a[lo - i1:]
    out = {"t_stage1_end": float(st.t_stage1_end), "t_start": float(t[lo]), "t_end": float(t[hi - 1]),
           "a_min": float(w.min()), "a_max": float(w.max()), "a_min_from_stage1": float(a.min()), "paper": paper,
           "t_paper": None}
    if paper is not None:
        cross = np.nonzero((a[:-1] - paper) * (a[1:] - paper) <= 0)[0]
        if cross.size:
            k = int(cross[0])
            f = (paper - a[k]) / (a[k + 1] - a[k]) if a[k + 1] != a[k] else 0.0
            out["t_paper"] = float(t[i1 + k] + f * (t[i1 + k + 1] - t[i1 + k]))
    return out


# --------------------------------------------------------------------------- computed side studies
RELAXATION_L = (2, 3, 4, 6, 8, 10, 13, 16, 20, 25, 30)
CUTOFF_L_MAX = (16, 20, 24, 28, 32, 36, 40, 48, 64, None)


def damped_pa_table(rows) -> dict:
    """The PA as each run's grid carries it (theory.grid_damping): {(S, N, kernel): {l_star, l_peak, t_star,
    decay}} for the quasi-spherical runs at L = 5 R. The damping comes from single-mode relaxation, not from
    wrinkling runs."""
    from ..analysis.sweep_fits import case_decay
    from ..analysis.theory import run_theory

    out = {}
    for r in rows:
        key = grid_key(r)
        if r["delta"] >= 0.5 or key in out or abs(r["L"] - 5.0) > 1e-9:
            continue
        th = run_theory(r["delta"], r["S"], grid_h=r["h"], kernel=r["kernel"], store_modes=False)
        try:
            decay = case_decay(th, "theory").exponent
        except (ValueError, ConfigError):
            decay = math.nan
        out[key] = {"l_star": float(th.l_star), "l_peak": float(th.l_peak), "t_star": float(th.t_star),
                    "decay": decay, "local_decay": local_decay(th, "theory", paper_decay(r["S"]))}
    return out


def relaxation_table(grids, ls=RELAXATION_L, tol=0.05) -> list[dict]:
    """IBM/theory relaxation-rate ratios of single modes (relaxation.py, clean interface, no box correction)
    on each ladder grid (N, vertices, L) -> rows {N, vertices, ratios, l_res}."""
    from .relaxation import l_res, mode_rate

    out = []
    for N, nv, L in grids:
        ratios = {l: mode_rate(l, N, nv, L=L).ratio for l in ls}
        # l = 2 is the one mode the periodic images slow (~5% at L = 5 R): l_res counts from l = 3
        out.append({"N": N, "vertices": nv, "L": L, "ratios": ratios,
                    "l_res": l_res({l: r for l, r in ratios.items() if l >= 3}, tol)})
    return out


def cutoff_table(fit, l_max_values=CUTOFF_L_MAX) -> dict | None:
    """The PA exponent b against the mode cutoff l_max (cutoff.py) over the S values of the report's PA fit."""
    from .cutoff import DEFAULT_LMAX_LABEL, exponent_vs_lmax

    kind = np.asarray(fit["kind"].values).astype(str)
    S = np.asarray(fit["S"].values, dtype=float)[kind == "theory"]
    delta = np.asarray(fit["delta"].values, dtype=float)[kind == "theory"]
    sel = np.abs(delta - 0.116) < 1e-6
    S = np.unique(S[sel])
    if len(S) < 3:
        return None
    ds = exponent_vs_lmax(0.116, list(S), list(l_max_values))
    rows = []
    for L in ds["l_max"].values:
        d = ds.sel(l_max=L)
        active = [float(s) for s, t in zip(ds["S"].values, d["truncated"].values, strict=True) if t]
        rows.append({"l_max": "default" if int(L) == DEFAULT_LMAX_LABEL else int(L), "b": float(d["b"]),
                     "low": float(d["b_low"]), "high": float(d["b_high"]),
                     "active_from": min(active) if active else None})
    return {"S": [float(x) for x in S], "rows": rows}




# --------------------------------------------------------------------------- selections and the fits' values
def ladder_rows(rows):
    """The resolution ladder's runs (tag ``ladder``; the finest rung is the fine group)."""
    return [r for r in rows if r["group"] in ("ladder", "fine") and r["tag"] and "ladder" in str(r["tag"])]


def fine_rows(rows):
    """The runs at the finest resolution, the per-case table and the exponent fit."""
    return [r for r in rows if r["group"] == "fine"]


def grid_key(r):
    """The key of the PA on run ``r``'s grid in ``damped_pa_table``."""
    return (r["S"], r["N"], r["kernel"])


def paper_grid_key(r):
    """The key of the PA on the paper's grid (PAPER_GRID, the default 4-point kernel) at run ``r``'s S."""
    return (r["S"], PAPER_GRID[0], DEFAULT_KERNEL)


def fit_decay(f, case_id):
    """(a, 95% low, 95% high) of the stage-2 decay fitted to ``case_id`` in fit.nc ``f``, None if not there."""
    if f is None or "case_id" not in f:
        return None
    ids = np.asarray(f["case_id"].values).astype(str)
    hit = np.nonzero(ids == case_id)[0]
    if not len(hit):
        return None
    c = f.isel(case=int(hit[0]))
    return float(c.decay_exponent), float(c.decay_ci_low), float(c.decay_ci_high)


def pa_fit_decay(f, delta, S):
    """The stage-2 decay exponent of this PA at (delta, S) in fit.nc ``f``, None if not there."""
    if f is None:
        return None
    for i in range(f.sizes["case"]):
        c = f.isel(case=i)
        if str(c.kind.values) == "theory" and abs(float(c.delta) - delta) < 1e-6 and abs(float(c.S) - S) < 1e-6:
            return float(c.decay_exponent)
    return None


def pa_fit_exponent(f, delta):
    """(b, 95% low, 95% high) of this PA's l_* ~ S^b at delta in fit.nc ``f`` (NaN if not fitted)."""
    for i in range(f.sizes["group"]):
        g = f.isel(group=i)
        if str(g.group_kind.values) == "theory" and abs(float(g.group_delta) - delta) < 1e-6:
            return float(g.l_star_exponent), float(g.l_star_ci_low), float(g.l_star_ci_high)
    return math.nan, math.nan, math.nan


def ladder_summary(rows) -> dict:
    """Per S of the quasi-spherical ladder: the rungs (sorted by h), the extrapolations (h^2 primary, h beside it)
    and the comparison with the paper's IBM l_* (within 10% or not; rule fixed in convergence.py)."""
    from .convergence import extrapolate, verdict

    out = {}
    ladder = [r for r in ladder_rows(rows) if r["delta"] < 0.5]
    for S in sorted({r["S"] for r in ladder}):
        rungs = sorted((r for r in ladder if r["S"] == S), key=lambda r: -r["h"])
        if len(rungs) < 2:
            continue
        h = [r["h"] for r in rungs]
        y = [r["sim_l_star"] for r in rungs]
        e2, e1 = extrapolate(h, y, order=2), extrapolate(h, y, order=1)
        paper = rungs[-1]["paper_ibm"]
        out[S] = {"rungs": rungs, "h2": e2, "h1": e1, "paper_ibm": paper, "pa": rungs[-1]["pa_l_star"],
                  "finest_verdict": verdict(y[-1], paper) if paper else "n/a",
                  "extrapolated_verdict": verdict(e2["value"], paper, low=e2["low"], high=e2["high"])
                  if paper else "n/a",
                  "increments": [b - a for a, b in zip(y, y[1:], strict=False)]}
    return out
