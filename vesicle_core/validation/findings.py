"""Validation report (issue 6), the findings: what each section of docs/validation.md states, decided from the
study's numbers (study.py).

One function per section template, ``templates/<name>.md.j2``: it returns the section's context, the rows of its
tables and every value and decision that its "Finding" sentences put into words (inside or outside an interval,
rising with N or not, which box is closer to the PA), or None (an empty list for the per-S findings) where the
section has nothing to show. The words are the templates'; the decisions are made here, from the numbers, and
nothing is tuned per case. ``sections(manifest, data)`` is the context of the whole report.
"""

from __future__ import annotations

import math

import numpy as np

from .claims import morphology_claims  # noqa: F401 -- the section of docs/validation_morphology.md
from .study import (
    PAPER_BOX_SHAPE,
    PAPER_EXPONENT_IBM,
    PAPER_EXPONENT_PA,
    fine_rows,
    fit_decay,
    grid_key,
    ladder_rows,
    ladder_summary,
    pa_fit_decay,
    pa_fit_exponent,
    paper_decay,
    paper_grid_key,
)


def _relative(x, ref):
    """x / ref - 1, None where there is no reference or no finite x (the tables' '-')."""
    return x / ref - 1 if ref and math.isfinite(x) else None


def _rising(values):
    return all(b > a for a, b in zip(values, values[1:], strict=False))


def _falling(values):
    return all(b < a for a, b in zip(values, values[1:], strict=False))


# --------------------------------------------------------------------------- l_* and its exponent
def ladder(summary, dpa=None) -> list[dict]:
    """Per S of the resolution ladder (ladder_summary): the rungs with the PA on each rung's grid, the finest rung
    and the two extrapolations against the paper's IBM l_* (Figs. 3, 5), and the trend of the rung-to-rung steps."""
    dpa = dpa or {}
    out = []
    for S, s in summary.items():
        paper, finest = s["paper_ibm"], s["rungs"][-1]
        inc = s["increments"]
        trend = "one step" if len(inc) < 2 else "shrinking" if _falling(inc) else "not shrinking"
        out.append({
            "S": S, "s": s, "e2": s["h2"], "e1": s["h1"], "finest": finest, "trend": trend,
            "rungs": [{**r, "grid_l_star": dpa.get(grid_key(r), {}).get("l_star"),
                       "grid_t_star": dpa.get(grid_key(r), {}).get("t_star"),
                       "sigma": r.get("sim_tension_reversal", math.nan), "wall_min": r["wall_s"] / 60}
                      for r in s["rungs"]],
            "damped_pa": damped_pa(s, dpa),
            "pa_stretch_tension": finest.get("pa_stretch_tension", math.nan),
            "vs_paper": {"finest": _relative(finest["sim_l_star"], paper), "h2": _relative(s["h2"]["value"], paper),
                         "h1": _relative(s["h1"]["value"], paper)},
            "models_differ": abs(s["h2"]["value"] - s["h1"]["value"])})
    return out


def damped_pa(s, dpa) -> dict | None:
    """Does the PA with each rung's mode damping (theory.grid_damping) follow the ladder? The ratios IBM l_* / the
    grid's PA l_* per N, their spread, and whether both rise with N."""
    pairs = [(r["N"], r["sim_l_star"], dpa[grid_key(r)]["l_star"]) for r in s["rungs"] if grid_key(r) in dpa]
    if len(pairs) < 2:
        return None
    ratios = [a / b for _, a, b in pairs]
    return {"ratios": [(x, N) for x, (N, _, _) in zip(ratios, pairs, strict=True)],
            "both_rise": _rising([p[1] for p in pairs]) and _rising([p[2] for p in pairs]),
            "spread": max(ratios) - min(ratios), "pa": s["pa"]}


def exponents(fine, summary, f, dpa=None) -> dict:
    """The exponent b of l_* ~ S^b (Fig. 4): the finest rung's fit and whether its interval holds the paper's IBM
    0.3923, the PA on the same grid and on the paper's grid (512^3) over the same S, this PA's fit (fit.nc) and
    the two-point exponents of a two-S ladder."""
    from ..analysis.fits import fit_power_law
    from .convergence import two_point_exponent

    qs = sorted((r for r in fine if r["delta"] < 0.5 and r["sim_l_star"] > 0), key=lambda r: r["S"])

    def grid_fit(key):  # the PA on a grid at the same S, if at least 3 of them were computed
        pts = [(r["S"], (dpa or {}).get(key(r), {}).get("l_star")) for r in qs]
        pts = [(S_, y) for S_, y in pts if y is not None and y > 0]
        return (fit_power_law(*zip(*pts, strict=True)), len(pts)) if len(pts) >= 3 else (None, len(pts))

    out = {"ibm": None, "own": None, "paper": None, "pa": None, "pair": None}
    if len(qs) >= 3:
        b = fit_power_law([r["S"] for r in qs], [r["sim_l_star"] for r in qs])
        (own, n_own), (paper, n_paper) = grid_fit(grid_key), grid_fit(paper_grid_key)
        out.update(ibm=b, N=qs[0]["N"], n=len(qs), own=own, n_own=n_own, paper=paper, n_paper=n_paper,
                   ibm_inside=b.ci_low <= PAPER_EXPONENT_IBM <= b.ci_high,
                   own_inside=own is not None and b.ci_low <= own.exponent <= b.ci_high,
                   paper_contains=paper is not None and paper.ci_low <= PAPER_EXPONENT_IBM <= paper.ci_high)
    pa = pa_fit_exponent(f, 0.116) if f is not None else (math.nan,) * 3
    if math.isfinite(pa[0]):
        out["pa"] = pa
    if len(summary) == 2:
        (S1, s1), (S2, s2) = summary.items()
        pairs = {r["N"]: r for r in s1["rungs"]}
        out["pair"] = {"S1": S1, "S2": S2,
                       "rungs": [(r2["N"], two_point_exponent(S1, pairs[r2["N"]]["sim_l_star"], S2, r2["sim_l_star"]))
                                 for r2 in s2["rungs"] if pairs.get(r2["N"])],
                       "h2": two_point_exponent(S1, s1["h2"]["value"], S2, s2["h2"]["value"])}
    return out


# --------------------------------------------------------------------------- stage-2 tension decay
def decay(summary, f, dpa=None) -> dict:
    """Per rung the fitted stage-2 decay exponent a (fit.nc) next to the PA on its grid, this PA and the paper's
    (Sec. V.A), and the finest rung per S."""
    dpa = dpa or {}
    rows = []
    for S, s in summary.items():
        paper, pa = paper_decay(S), pa_fit_decay(f, 0.116, S)
        for r in s["rungs"]:
            a, low, high = fit_decay(f, r["case_id"]) or (None, None, None)
            rows.append({"S": S, "N": r["N"], "a": a, "low": low, "high": high,
                         "grid": dpa.get(grid_key(r), {}).get("decay"), "pa": pa, "paper": paper})
    n_max = max(r["N"] for r in rows) if rows else None
    finest = [{**r, "fitted": r["a"] is not None and math.isfinite(r["a"])} for r in rows if r["N"] == n_max]
    return {"rows": rows, "damped_decay": damped_decay(rows), "finest": finest}


def damped_decay(rows) -> list[dict]:
    """Per S (rows of ``decay``): IBM a minus the grid's PA a per rung, at how many rungs the grid's PA value lies
    inside the IBM's 95% interval, and whether both fall with every refinement."""
    out = []
    for S in sorted({r["S"] for r in rows}):
        rs = [r for r in rows if r["S"] == S and r["a"] is not None and r["grid"] is not None
              and math.isfinite(r["a"]) and math.isfinite(r["grid"])]
        if len(rs) < 2:
            continue
        out.append({"S": S, "diffs": [(r["a"] - r["grid"], r["N"]) for r in rs], "n": len(rs),
                    "inside": sum(1 for r in rs if r["low"] <= r["grid"] <= r["high"]),
                    "both_fall": _falling([r["a"] for r in rs]) and _falling([r["grid"] for r in rs])})
    return out


def _local_decay_entry(S, curve, v, N=None) -> dict:
    spread = v["a_max"] / v["a_min"] if v["a_min"] > 0 else math.inf
    return {"S": S, "curve": curve, "N": N, "v": v, "spread": spread, "varies": spread > 1.1,
            "before": v["t_paper"] is not None and v["t_paper"] < v["t_start"]}


def local_decay(pa_local, summary, dpa=None) -> list[dict]:
    """Is stage 2 one power law? Per S the local exponent (study.local_decay) of this PA, of the PA on the finest
    rung's grid and of the finest rung's run: whether it varies by more than 10% inside the fitted window and
    where it equals the paper's exponent."""
    entries = []
    for S, s in (summary or {}).items():
        pa = (pa_local or {}).get(("PA", S))
        if pa:
            entries.append(_local_decay_entry(S, "pa", pa))
        finest = max(s["rungs"], key=lambda r: r["N"]) if s.get("rungs") else None
        if finest is None:
            continue
        grid = dpa.get(grid_key(finest), {}).get("local_decay") if dpa else None
        if grid:
            entries.append(_local_decay_entry(S, "grid", grid, finest["N"]))
        if finest.get("local_decay"):
            entries.append(_local_decay_entry(S, "ibm", finest["local_decay"], finest["N"]))
    return entries


def local_decay_clause(v) -> dict | None:
    """For the conclusions: does this PA's own stage-2 curve make the exponent depend on the fitting window?"""
    if not v or not v["a_min"] > 0:
        return None
    spread = v["a_max"] / v["a_min"]
    return {"spread": spread, "constant": spread <= 1.1, "t_paper": v["t_paper"]}


# --------------------------------------------------------------------------- side studies
def relaxation(table, summary) -> dict:
    """The single-mode relaxation ratios per ladder grid, and the ratio at each rung's own dominant mode l_peak
    (interpolated in l)."""
    ls = list(table[0]["ratios"])
    peaks = []
    for S, s in summary.items():
        for r in s["rungs"]:
            t = next((t for t in table if t["N"] == r["N"]), None)
            lp = r["sim_l_peak"]
            if t and math.isfinite(lp):
                peaks.append({"S": S, "N": r["N"], "l_peak": lp,
                              "ratio": float(np.interp(lp, ls, [t["ratios"][l] for l in ls]))})
    return {"ls": ls, "table": table, "peaks": peaks}


def seeds(rows, dpa=None) -> dict | None:
    """The seed runs against the ladder's mesh-noise run at the same S and N: how far the thermal seeds move l_*
    and t_*, and, started from the PA's own spectrum, how far the IBM is from the PA on its grid."""
    dpa = dpa or {}
    runs = [r for r in rows if r["group"] == "seed"]
    if not runs:
        return None
    base = {(r["S"], r["N"], r["vertices"]): r for r in rows if r["group"] in ("ladder", "fine")}
    table, changes, closure = [], [], []
    for S in sorted({r["S"] for r in runs}):
        grp = [r for r in runs if r["S"] == S]
        b = base.get((S, grp[0]["N"], grp[0]["vertices"]))
        g = dpa.get(grid_key(grp[0]), {})
        grid = {"S": S, "N": grp[0]["N"], "grid_l_star": g.get("l_star"), "grid_t_star": g.get("t_star")}
        if b:
            table.append({**b, **grid, "seed_scale": None})
        for r in sorted(grp, key=lambda r: r["seed_scale"]):
            table.append({**r, **grid})
            if b:
                changes.append({"S": S, "scale": r["seed_scale"], "l_star": r["sim_l_star"] / b["sim_l_star"] - 1,
                                "t_star": r["sim_t_star"] - b["sim_t_star"]})
            if r["seed_scale"] == 1.0 and g:
                closure.append({"S": S, "N": r["N"], "grid": r["sim_l_star"] / g["l_star"] - 1,
                                "pa": r["sim_l_star"] / r["pa_l_star"] - 1,
                                "mesh": b["sim_l_star"] / g["l_star"] - 1 if b else math.nan})
    worst = max(changes, key=lambda c: abs(c["l_star"])) if changes else None
    return {"table": table, "changes": changes, "worst": worst, "closure": closure}


def variations(rows, dpa=None) -> list[dict] | None:
    """Each one-change run against the ladder run at the same S and N: the relative change of l_*, and of the PA
    on the changed grid."""
    dpa = dpa or {}
    var = [r for r in rows if r["group"] == "variation"]
    if not var:
        return None
    base = {(r["S"], r["N"]): r for r in ladder_rows(rows)}
    out = []
    for r in var:
        b = base.get((r["S"], r["N"]))
        if b:
            g0, g1 = dpa.get(grid_key(b), {}).get("l_star"), dpa.get(grid_key(r), {}).get("l_star")
            out.append({"r": r, "b": b, "rel": r["sim_l_star"] / b["sim_l_star"] - 1,
                        "grid_rel": g1 / g0 - 1 if g0 and g1 else None})
    return out


def box(b) -> dict:
    """The periodic-box test (box.box_comparison) and whether its largest shape difference is within Table I's."""
    return {"b": b, "shape_within_paper": b["max_shape_error"] <= PAPER_BOX_SHAPE, "box_tension": box_tension(b)}


def box_tension(b) -> dict | None:
    """The tension at the reversal in the two boxes and at L -> infinity (box.image_extrapolation) against the PA's
    (S - Gamma_2) / A_2 (eq. 12), and whether the larger box is closer to the unbounded PA."""
    s, g, inf, pa = b["tension_small"], b["tension_large"], b["tension_unbounded"], b.get("tension_pa", math.nan)
    if not (math.isfinite(s) and math.isfinite(g)):
        return None
    has_pa = math.isfinite(pa)
    shape = b.get("reversal_shape_error", math.nan)
    # "far more": the tension's relative change is ten times the relative shape difference at the same frame
    dominates = abs(g / s - 1) > 10 * shape if math.isfinite(shape) else None
    return {"b": b, "shape": shape, "tension_dominates": dominates,
            "small": s, "large": g, "unbounded": inf, "pa": pa, "has_pa": has_pa, "change": g / s - 1,
            "small_vs_pa": s / pa - 1 if has_pa else None, "large_vs_pa": g / pa - 1 if has_pa else None,
            "unbounded_vs_pa": inf / pa - 1 if has_pa else None,
            "closer": abs(g - pa) < abs(s - pa) if has_pa else None}


def cost(rows, target_h=3.0, jobs=2) -> dict | None:
    """Simulation wall time per grid, and what the study costs on a machine that runs ``jobs`` at once: above or
    within a ``target_h`` hour sitting, or open where resumed runs' earlier calls were not timed."""
    walls = [(r["N"], r["wall_s"]) for r in rows if math.isfinite(r["wall_s"])]
    if not walls:
        return None
    total = sum(w for _, w in walls)
    table = []
    for N in sorted({n for n, _ in walls}):
        w = [x for n, x in walls if n == N]
        table.append({"N": N, "runs": len(w), "total_min": sum(w) / 60, "median_min": float(np.median(w)) / 60,
                      "share": sum(w) / total})
    partial = [r["case_id"] for r in rows if r.get("wall_partial")]
    elapsed = total / jobs / 3600
    return {"table": table, "partial": partial, "runs": len(walls), "total_h": total / 3600, "jobs": jobs,
            "elapsed_h": elapsed, "target_h": target_h, "biggest": max(table, key=lambda t: t["total_min"]),
            "verdict": "above" if elapsed > target_h else "open" if partial else "within"}


def cutoff(c) -> dict:
    """The PA exponent against its mode cutoff (cutoff.py): the cutoffs whose interval holds the paper's PA 0.372,
    and whether every one of them truncates l_* inside the S range."""
    hit = [r for r in c["rows"] if r["low"] <= PAPER_EXPONENT_PA <= r["high"]]
    capped = [r for r in hit if r["active_from"]]
    return {"c": c, "hit": hit, "capped": capped, "all_capped": len(capped) == len(hit)}


def coarse(rows) -> list[tuple] | None:
    """The coarse copy of each fine case at the same (S, Delta)."""
    runs = [r for r in rows if r["group"] == "coarse"]
    if not runs:
        return None
    fine = fine_rows(rows)
    pairs = [(c, next((r for r in fine if abs(r["S"] - c["S"]) < 1e-6 and abs(r["delta"] - c["delta"]) < 1e-6),
                      None)) for c in runs]
    return [(c, m) for c, m in pairs if m]


# --------------------------------------------------------------------------- conclusions
def _decay_trends(summary, f, pa_local) -> list[dict]:
    """Per S: the finest rungs' decay exponents against the paper's, whether they fall with every refinement, on
    which side of the finest rung the paper's value lies, and this PA's local exponent (local_decay_clause)."""
    out = []
    for S, s in summary.items():
        a = [(r["N"], fit_decay(f, r["case_id"])) for r in s["rungs"]]
        a = [(N, d[0]) for N, d in a if d and math.isfinite(d[0])]
        paper = paper_decay(S)
        if len(a) >= 2 and paper:
            out.append({"S": S, "a": a, "paper": paper, "falling": _falling([x for _, x in a]),
                        "paper_below": paper < a[-1][1], "clause": local_decay_clause(pa_local.get(("PA", S)))})
    return out


def discussion(data, summary=None) -> dict | None:
    """Statements derived from the numbers (no per-case tuning): the IBM over the PA at the finest resolution, the
    ladder's verdicts, the relaxation of l = 25, the decay exponents' trend, the largest one-change lever and the
    stage-1 growth. None without a fine group."""
    fine = fine_rows(data["rows"])
    if not fine:
        return None
    pairs = sorted((r["S"], r["sim_l_star"] / r["pa_l_star"], r["delta"]) for r in fine
                   if r["pa_l_star"] > 0 and math.isfinite(r["sim_l_star"]))
    above = sum(1 for p in pairs if p[1] > 1)
    growth = [r["growth_decades"] for r in fine if r["delta"] < 0.5]
    out = {"pairs": pairs, "above": above, "trend": "above" if above == len(pairs) else "below" if not above else
           "mixed", "summary": summary or {}, "relaxation": None, "decay": [], "moves": [],
           "growth": (min(growth), max(growth)) if growth else None}
    rel = data.get("relaxation")
    if rel:
        t = max(rel, key=lambda t: t["N"])
        if t["ratios"].get(25) is not None:
            # damped: slower than theory by more than the 5% that defines l_res
            out["relaxation"] = {"N": t["N"], "ratio": t["ratios"][25], "l_res": t["l_res"],
                                 "damped": t["ratios"][25] < 0.95}
    f = data["fits"].get("fine")
    if summary and f is not None:
        out["decay"] = _decay_trends(summary, f, data.get("pa_local_decay", {}))
    base = {(r["S"], r["N"]): r for r in ladder_rows(data["rows"])}
    out["moves"] = [(r["tag"], r["sim_l_star"] / base[(r["S"], r["N"])]["sim_l_star"] - 1)
                    for r in data["rows"] if r["group"] == "variation" and (r["S"], r["N"]) in base]
    out["biggest_move"] = max(out["moves"], key=lambda m: abs(m[1])) if out["moves"] else None
    out["moves_N"] = sorted({r["N"] for r in data["rows"] if r["group"] == "variation" and (r["S"], r["N"]) in base})
    return out


def sections(manifest, data) -> dict:
    """The context of templates/validation.md.j2: every section's, None where a section is left out."""
    rows, f, dpa = data["rows"], data["fits"].get("fine"), data.get("damped_pa")
    fine = fine_rows(rows)
    summary = ladder_summary(rows)
    return {
        "manifest": manifest, "rows": rows, "fine": fine,
        "ladder": ladder(summary, dpa) if summary else None,
        "exponents": exponents(fine, summary, f, dpa),
        "decay": decay(summary, f, dpa) if summary else None,
        "local_decay": local_decay(data.get("pa_local_decay"), summary, dpa) if summary else None,
        "relaxation": relaxation(data["relaxation"], summary) if data.get("relaxation") else None,
        "seeds": seeds(rows, dpa), "variations": variations(rows, dpa),
        "box": box(data["box"]) if data["box"] else None,
        "cutoff": cutoff(data["cutoff"]) if data.get("cutoff") else None,
        "cost": cost(rows),
        "coarse": coarse(rows) if manifest.get("coarse_rows", True) else None,
        "discussion": discussion(data, summary),
    }
