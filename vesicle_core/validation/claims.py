"""The paper's three claims about the wrinkle pattern, decided from the runs' morphology (microscope.nc).

The paper names its patterns by eye (Sec. V.B, Appendix C, Fig. 9):

1. the wrinkles form a "highly disordered zigzag herringbone" pattern;
2. in strong flow they "tend to be peanut shaped";
3. they are "concentrated around the poles, where the membrane is compressed".

Each claim is decided here from numbers that the classifier (analysis.pattern_class, thresholds from synthetic
fields only) and the wrinkle location (analysis.wrinkle_location) produce, with rules fixed before the runs were
seen; the template morphology_claims.md.j2 puts the decisions into words.

* **Claim 1** holds in a case when its pattern at t_* (argmin Delta_2, the paper's moment of l_*) is classed
  herringbone: the crests share an axis only in part (herringbone threshold <= P < ripples threshold). The verdict:
  "holds" in every case, "holds in part" in some, "does not hold" in none.
* **Claim 2**, per Delta with two or more flow strengths: the share of a case's wrinkled key frames (t_* and the
  paper's snapshot times inside the run, counted only where the outline shows wrinkles, i.e. k_* is defined: the
  class of a frame without wrinkles says nothing about their shape) classed peanut, 0 if none is wrinkled; the
  claim holds at that Delta when the strongest flow's share is above zero and above the weakest flow's. The
  verdict: holds at every Delta, in part, or at none.
* **Claim 3** holds in a case when at t_* the polar caps about the compressional axis carry the most wrinkle energy
  per area of all latitude bands, more than their area share (enrichment > 1), and the wrinkle energy is
  anti-correlated with the local tension (correlation < 0: more wrinkles where the tension is more negative,
  i.e. compressive). The verdict: every case, some, none.
"""

from __future__ import annotations

import json
import math

import numpy as np

from ..analysis.pattern_class import THRESHOLDS
from ..analysis.pattern_synth import CLASSES

__all__ = ["COST_BUDGET", "case_row", "morphology_claims"]

#: the issue's budget for the microscope and the metrics: a share of the run's own wall time
COST_BUDGET = 0.10


def _verdict(n_yes, n):
    return "none" if n == 0 else "holds" if n_yes == n else "in part" if n_yes > 0 else "does not hold"


def _f(ds, name, j):
    return float(ds[name].values[j]) if name in ds and j is not None else math.nan


def _float_list(value):
    """A list attribute as read back from netCDF: an array, a number, or the JSON text of an empty list."""
    if isinstance(value, str):
        value = json.loads(value) if value.strip().startswith("[") else []
    return [float(x) for x in np.atleast_1d(value)]


def _series(mic, morph_time, patterns, time):
    """The morphology per classified frame, with k_* of the outline at the same frame."""
    names = {"P": "crest_alignment", "low": "low_degree_fraction", "A": "ec_asymmetry", "l_c": "l_c",
             "polar_enrichment": "polar_enrichment", "corr": "tension_correlation"}
    return [{"t": float(t), "pattern": p, **{k: _f(mic, n, j) for k, n in names.items()},
             "k_star": float(mic["k_star"].values[int(np.argmin(np.abs(time - t)))])}
            for j, (t, p) in enumerate(zip(morph_time, patterns, strict=True))]


def case_row(case_id, mic, l_star=math.nan) -> dict:
    """One case's numbers from its microscope.nc (an xarray Dataset with the morphology): the class and features
    at t_*, the classes at the paper's times, its morphology time series, k_* at t_* and the cost."""
    a = mic.attrs
    names = a.get("pattern_classes", " ".join(CLASSES)).split()
    pat = [names[int(p)] for p in mic["pattern"].values] if "pattern" in mic else []
    mt = np.asarray(mic["morph_time"].values, float) if "morph_time" in mic.coords else np.zeros(0)
    star = np.flatnonzero(np.asarray(mic["is_t_star"].values) == 1) if "is_t_star" in mic else []
    j = int(star[0]) if len(star) else None
    time = np.asarray(mic["time"].values, float)
    # a frame is wrinkled when the microscope sees wrinkles on its outline (k_* defined: above the resolution)
    wrinkled = [bool(np.isfinite(mic["k_star"].values[int(np.argmin(np.abs(time - t)))])) for t in mt]
    paper, key = {}, []
    if "paper_time" in mic:
        for k, t in enumerate(np.asarray(mic["paper_time"].values, float)):
            if math.isfinite(t):
                paper[float(t)] = pat[k]
                key += [pat[k]] if wrinkled[k] and k != j else []
    key += [pat[j]] if j is not None and wrinkled[j] else []
    k_star = float(mic["k_star"].values[int(np.argmin(np.abs(time - mt[j])))]) if j is not None else math.nan
    wall = float(np.asarray(a.get("wall_time_s", math.nan)).ravel()[0])
    outline_s, morph_s = float(a.get("microscope_wall_time_s", math.nan)), float(a.get("morphology_wall_time_s", 0))
    enrich = mic["enrichment"].values[j] if j is not None and "enrichment" in mic else np.array([math.nan])
    band_t = mic["band_tension"].values[j] if j is not None and "band_tension" in mic else np.array([math.nan])
    return {
        # the meshed Delta of two meshes of one case differs at 1e-14: rounded, they group together
        "case_id": case_id, "delta": round(float(np.asarray(a.get("delta", math.nan)).ravel()[0]), 6),
        "S": round(float(np.asarray(a.get("S", math.nan)).ravel()[0]), 6),
        "N": int(np.asarray(a.get("N", 0)).ravel()[0]),
        "vertices": int(mic.attrs.get("mesh_n_vertices", 0) or 0),
        "t_star": mt[j] if j is not None else math.nan, "l_star": float(l_star), "k_star": k_star,
        "pattern_t_star": pat[j] if j is not None else "-", "paper": paper,
        "paper_outside": _float_list(a.get("paper_times_outside", [])),
        "P": _f(mic, "crest_alignment", j), "low": _f(mic, "low_degree_fraction", j),
        "A": _f(mic, "ec_asymmetry", j), "l_c": _f(mic, "l_c", j),
        "defects": float(mic["defect_density"].values[j, 1]) if j is not None and "defect_density" in mic
        else math.nan,
        "polar_enrichment": _f(mic, "polar_enrichment", j), "corr": _f(mic, "tension_correlation", j),
        "max_band": int(np.nanargmax(enrich)) if np.isfinite(enrich).any() else -1, "n_bands": len(enrich),
        "polar_tension": float(band_t[-1]), "equator_tension": float(band_t[0]),
        "peanut_share": sum(p == "peanut" for p in key) / len(key) if key else 0.0, "n_key": len(key),
        "wrinkled_t_star": bool(j is not None and wrinkled[j]),
        "series": _series(mic, mt, pat, time),
        "wall_s": wall, "outline_s": outline_s, "morphology_s": morph_s,
        "cost": (outline_s + morph_s) / wall if wall > 0 else math.nan,
    }


def _claim1(rows):
    ok = [r for r in rows if r["pattern_t_star"] == "herringbone"]
    others = {}
    for r in rows:
        if r["pattern_t_star"] != "herringbone":
            others[r["pattern_t_star"]] = others.get(r["pattern_t_star"], 0) + 1
    exp = [r for r in rows if r["delta"] > 0.5]
    return {"n": len(rows), "n_yes": len(ok), "verdict": _verdict(len(ok), len(rows)), "others": others,
            "P": [(r["P"], r["S"], r["delta"]) for r in rows], "low": THRESHOLDS.herringbone,
            "high": THRESHOLDS.ripples, "n_exp": len(exp),
            "n_exp_yes": sum(r["pattern_t_star"] == "herringbone" for r in exp)}


def _claim2(rows):
    per = []
    for d in sorted({r["delta"] for r in rows}):
        rs = sorted((r for r in rows if r["delta"] == d), key=lambda r: r["S"])
        if len(rs) < 2:
            continue
        weak, strong = rs[0], rs[-1]
        holds = strong["peanut_share"] > 0 and strong["peanut_share"] > weak["peanut_share"]
        per.append({"delta": d, "weak": weak, "strong": strong, "holds": bool(holds)})
    return {"per_delta": per, "n": len(per), "n_yes": sum(p["holds"] for p in per),
            "verdict": _verdict(sum(p["holds"] for p in per), len(per)), "threshold": THRESHOLDS.low_degree}


def _claim3(rows):
    out = []
    for r in rows:
        polar = r["max_band"] == r["n_bands"] - 1 and r["polar_enrichment"] > 1
        compressed = r["corr"] < 0
        out.append({**r, "polar": bool(polar), "compressed": bool(compressed), "holds": bool(polar and compressed)})
    n_yes = sum(r["holds"] for r in out)
    exp = [r for r in out if r["delta"] > 0.5]
    return {"rows": out, "n": len(out), "n_yes": n_yes, "verdict": _verdict(n_yes, len(out)), "n_exp": len(exp),
            "n_exp_yes": sum(r["holds"] for r in exp),
            "n_polar": sum(r["polar"] for r in out), "n_compressed": sum(r["compressed"] for r in out)}


def _cost(rows):
    fr = [r["cost"] for r in rows if math.isfinite(r["cost"])]
    return {"rows": rows, "budget": COST_BUDGET, "n": len(fr), "n_within": sum(c <= COST_BUDGET for c in fr),
            "max": max(fr) if fr else math.nan, "median": float(np.median(fr)) if fr else math.nan}


def morphology_claims(rows, missing=()) -> dict | None:
    """The context of templates/morphology_claims.md.j2 from :func:`case_row` rows (sorted by Delta, then S);
    ``missing``: the paper's cases that have no microscope.nc yet. None without rows."""
    if not rows:
        return None
    rows = sorted(rows, key=lambda r: (r["delta"], r["S"]))
    return {"rows": rows, "missing": list(missing), "claim1": _claim1(rows), "claim2": _claim2(rows),
            "claim3": _claim3(rows), "cost": _cost(rows), "thresholds": THRESHOLDS, "classes": CLASSES}
