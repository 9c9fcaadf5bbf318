"""Fits across a sweep from its datasets: each case's stage-2 tension decay (:func:`case_decay`) and l_* ~ S^b per
(kind, Delta) group, in one Dataset (:func:`sweep_fit_dataset`, written by ``vesicle fit``). The fits themselves
and their intervals: :mod:`vesicle_core.analysis.fits`."""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from .fits import TensionDecayFit, fit_power_law, tension_decay

__all__ = ["FINEST", "case_decay", "sweep_fit_dataset"]


def case_decay(ds, kind, confidence: float = 0.95) -> TensionDecayFit:
    """Stage-2 decay fit of one dataset's sigma(time) after the reversal; the simulation's noisier tension is
    smoothed over 3 frames and its stage windows may deviate 5% from a power law (the PA's 1%)."""
    t = np.asarray(ds["time"].values, dtype=float)
    sig = np.asarray(ds["sigma"].values, dtype=float)
    keep = t > 0
    return tension_decay(t[keep], sig[keep], confidence=confidence, smooth=1 if kind == "theory" else 3,
                         rms_tol=0.01 if kind == "theory" else 0.05)


FINEST = -1  # group_N and group_vertices of a group that takes each S at its finest resolution


def _group_key(r):
    """A fit group: one kind, Delta, resolution and temperature (the seeds of an ensemble fall in one group)."""
    return (r["kind"], r["delta"], r["N"], r["vertices"], r["kT"])


def _groups(rows) -> dict:
    """Fit groups -> their rows: one per resolution, and, for a simulated Delta (and kT) run at several resolutions,
    one more (N = vertices = FINEST) that takes each S at its finest rung (largest N, then vertex count), so that a
    sweep whose points were each run where their l_* stopped moving is fitted as one set."""
    groups = {}
    for r in rows:
        groups.setdefault(_group_key(r), []).append(r)
    ladders = {}
    for kind, delta, N, nv, kT in groups:
        if kind == "simulation":
            ladders.setdefault((delta, kT), set()).add((N, nv))
    for (delta, kT), rungs in ladders.items():
        if len(rungs) < 2:
            continue
        sel = [r for r in rows if r["kind"] == "simulation" and r["delta"] == delta and r["kT"] == kT]
        finest = {}
        for r in sel:
            finest[r["S"]] = max(finest.get(r["S"], (0, 0)), (r["N"], r["vertices"]))
        best = [r for r in sel if (r["N"], r["vertices"]) == finest[r["S"]]]
        groups[("simulation", delta, FINEST, FINEST, kT)] = best
    return dict(sorted(groups.items()))


def _ensemble_points(groups: dict) -> dict:
    """Per (group, S): the number of seeds and the mean and sample standard deviation of l_*, l_peak, t_* over them
    (dimension ``point``; sd NaN for a single run). An ensemble's l_* is a distribution, not one value."""
    out = {"point_group": [], "point_S": [], "point_n_seeds": []}
    for name in ("l_star", "l_peak", "t_star"):
        out[f"point_{name}_mean"], out[f"point_{name}_sd"] = [], []
    for g, members in enumerate(groups.values()):
        for S in sorted({r["S"] for r in members}):
            sel = [r for r in members if r["S"] == S]
            out["point_group"].append(g)
            out["point_S"].append(S)
            out["point_n_seeds"].append(len(sel))
            for name in ("l_star", "l_peak", "t_star"):
                v = np.array([r[name] for r in sel], dtype=float)
                out[f"point_{name}_mean"].append(float(np.mean(v)))
                out[f"point_{name}_sd"].append(float(np.std(v, ddof=1)) if v.size > 1 else math.nan)
    return {k: ("point", np.array(v)) for k, v in out.items()}


def _group_fits(groups: dict, confidence: float, min_points: int) -> dict:
    """Per group: its key's fields, its size and the power laws of l_* and l_peak in S (NaN where it has fewer than
    ``min_points`` points or a single S)."""
    gdata = {k: [] for k in ("group_kind", "group_delta", "group_N", "group_vertices", "group_kT", "n_cases")}
    for name in ("l_star", "l_peak"):
        for k in ("exponent", "ci_low", "ci_high", "prefactor", "r2"):
            gdata[f"{name}_{k}"] = []
    for key, sel in groups.items():
        kind, delta, N, nv, kT = key
        gdata["group_kind"].append(kind)
        gdata["group_delta"].append(delta)
        gdata["group_N"].append(N)
        gdata["group_vertices"].append(nv)
        gdata["group_kT"].append(kT)
        gdata["n_cases"].append(len(sel))
        for name in ("l_star", "l_peak"):
            pts = [(r["S"], r[name]) for r in sel if np.isfinite(r[name]) and r[name] > 0]
            fit = None
            # an ensemble at one S (every seed a point, one x) has no exponent: NaN, as a group too small
            if len(pts) >= min_points:
                x, y = map(np.asarray, zip(*pts, strict=True))
                if np.ptp(np.log(x)) > 1e-9:
                    fit = fit_power_law(x, y, confidence)
            for k in ("exponent", "ci_low", "ci_high", "prefactor", "r2"):
                gdata[f"{name}_{k}"].append(getattr(fit, k) if fit is not None else math.nan)
    return gdata


def _l_star(ds) -> dict:
    """The l_* and t_* a fit uses: between the frames (spectra's ``l_star_fit``, ``t_star_fit``), which do not jump
    by a frame when the frame grid moves, where the dataset has them; else the frame values (theory datasets, whose
    output times are dense, 401 in the workflow, and spectra written before the fit existed). The frame values stay
    in ``l_star_frame``, ``t_star_frame``."""
    frame = {"l_star_frame": float(ds["l_star"]), "t_star_frame": float(ds["t_star"])}
    if "l_star_fit" in ds and "t_star_fit" in ds:
        return {"l_star": float(ds["l_star_fit"]), "t_star": float(ds["t_star_fit"]), **frame}
    return {"l_star": frame["l_star_frame"], "t_star": frame["t_star_frame"], **frame}


def sweep_fit_dataset(datasets, confidence: float = 0.95, min_points: int = 3):
    """Fits across a sweep: l_* ~ S^b per (kind, Delta) group and the stage-2 tension decay per case.

    ``datasets`` are spectra (simulation) or theory (PA) Datasets with scalars ``l_star`` (eq. 31), ``l_peak``
    (dominant mode at t_*), ``t_star`` (and, in spectra, ``l_star_fit``, ``t_star_fit``, which the fits then use:
    :func:`_l_star`), the series ``sigma(time)`` and attrs ``delta`` and ``S``. A group with
    fewer than ``min_points`` cases or a single S (an ensemble at one flow strength) gets a NaN exponent; a case
    whose tension has no clean stage 2 gets NaN and a ``note``.
    Returns a Dataset with a ``case`` dimension (per-file values), a ``group`` dimension (per-sweep fits: one
    kind, Delta, N, vertex count and kT; where a simulated Delta was run at several resolutions, one more group with
    N = vertices = FINEST (-1) takes each S at its finest rung) and a ``point`` dimension (per group and S: mean and
    spread over the noise seeds of an ensemble). An ensemble's fit uses every seed's l_* as a point, so its interval
    carries the scatter over seeds.
    """
    import xarray as xr

    rows = []
    for ds in datasets:
        kind = "theory" if "face_tension_mean" not in ds else "simulation"
        try:
            # simulations: the target Delta of the mesh (the meshed value differs by the faceting)
            delta = float(ds.attrs.get("mesh_target_delta", ds.attrs["delta"]))
            S = float(ds.attrs["S"])
        except KeyError as exc:
            raise ConfigError(f"dataset {ds.attrs.get('case_id', '?')} lacks the attribute {exc}") from None
        # a sweep group is one resolution: cases at other N or vertex counts (convergence copies, box tests)
        # are fitted separately, and together in one more group that takes each S at its finest rung (_groups)
        N = int(ds.attrs.get("N", 0)) if kind == "simulation" else 0
        nv = int(ds.attrs.get("mesh_n_vertices", ds.attrs.get("n_node", 0))) if kind == "simulation" else 0
        kT = float(ds.attrs.get("kT", 0.0)) if kind == "simulation" else 0.0
        seed = int(ds.attrs.get("noise_seed", 0)) if kT > 0 else -1
        row = {"kind": kind, "delta": delta, "S": S, "N": N, "vertices": nv, "kT": kT, "noise_seed": seed,
               "case_id": str(ds.attrs.get("case_id", f"{kind}_D{delta:g}_S{S:g}")), **_l_star(ds),
               "l_peak": float(ds["l_peak"]) if "l_peak" in ds else math.nan, "decay_exponent": math.nan,
               "decay_ci_low": math.nan, "decay_ci_high": math.nan, "t_stage2_start": math.nan,
               "t_stage2_end": math.nan, "note": ""}
        try:
            d = case_decay(ds, kind, confidence)
            row.update(decay_exponent=d.exponent, decay_ci_low=d.ci_low, decay_ci_high=d.ci_high,
                       t_stage2_start=d.stages.t_stage2_start, t_stage2_end=d.stages.t_stage2_end)
        except (ConfigError, ValueError) as exc:
            row["note"] = f"no stage-2 fit: {exc}"
        rows.append(row)
    if not rows:
        raise ConfigError("no datasets to fit")
    case = {k: ("case", np.array([r[k] for r in rows])) for k in rows[0]}
    groups = _groups(rows)
    gdata = _group_fits(groups, confidence, min_points)
    group = {k: ("group", np.array(v)) for k, v in gdata.items()}
    out = xr.Dataset({**case, **group, **_ensemble_points(groups)})
    units = {"S": "1", "delta": "1", "l_star": "1", "l_peak": "1", "t_star": "1/gamma_dot", "l_star_frame": "1",
             "t_star_frame": "1/gamma_dot"}
    for k, u in units.items():
        out[k].attrs["units"] = u
    out["l_star"].attrs["long_name"] = ("l_* of eq. (31) at t_*, between the frames where the dataset has it "
                                        "(spectra's l_star_fit), else at the frame")
    out["t_star"].attrs["long_name"] = "t_*, between the frames where the dataset has it (spectra's t_star_fit)"
    out["l_star_frame"].attrs["long_name"] = "l_* of eq. (31) at the frame where Delta_2 is smallest"
    out["t_star_frame"].attrs["long_name"] = "the frame where Delta_2 is smallest"
    out["l_peak"].attrs["long_name"] = "dominant mode argmax_{l>=3} Delta_l at t_* (Sec. V.A)"
    out["decay_exponent"].attrs["long_name"] = "stage-2 exponent a of |sigma| ~ t^-a"
    out["l_star_exponent"].attrs["long_name"] = "exponent b of l_* (eq. 31) ~ S^b within the group"
    out["l_peak_exponent"].attrs["long_name"] = "exponent b of l_peak ~ S^b within the group"
    out["point_l_star_sd"].attrs["long_name"] = "sample standard deviation of l_* over the noise seeds at this S"
    out["kT"].attrs["units"] = "kappa"
    out.attrs.update(confidence=confidence, min_points=min_points,
                     method="OLS in log-log with Student-t intervals; stage 2 found by fits.detect_tension_stages")
    return out
