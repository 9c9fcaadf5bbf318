"""Validation study (issue 6): the project's numbers next to the paper's and next to theory.

``write_report(manifest, out_md)`` turns a manifest of produced files into ``docs/validation.md``:
per-case l_* (simulation, this project's PA, the paper's PA and IBM values), the fitted exponents of
l_* against S with intervals next to the paper's 0.3923 (IBM) and 0.372 (PA) and Turitsyn's 1/3,
stage-2 tension decay exponents next to the paper's 0.74 and 0.81, area/volume drift, time step, steps
and wall time per run, a resolution-convergence comparison, the periodic-box test (Table I) and the
figures. Nothing here is tuned per case: every number is read from the files.

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
from pathlib import Path

import numpy as np

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


def _paper_lstar(delta, S):
    for (d, s), v in PAPER_L_STAR.items():
        if abs(d - delta) < 0.02 and abs(s - S) / s < 0.02:
            return v
    return None


def _fmt(x, nd=3):
    if x is None:
        return "-"
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if not math.isfinite(x):
        return "-"
    if x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e5):
        return f"{x:.2e}"
    return f"{x:.{nd}g}"


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


def box_comparison(traj_small, traj_large) -> dict:
    """Table I: maximum relative difference of the membrane shape and velocity between two box sizes.

    Frames are matched by time; the velocity is the centred difference of consecutive frames. Errors are
    max_k |a_k - b_k| / max_k |a_k| per frame, then the maximum over frames (shape) and the median and
    maximum over frames (velocity, whose small-|u| frames inflate the ratio as the paper notes).
    """
    ta = traj_small["time"].values
    tb = traj_large["time"].values
    common = np.intersect1d(np.round(ta, 9), np.round(tb, 9))
    if len(common) < 3:
        raise ValueError("the two box runs share fewer than 3 output times: run both with the same fixed dt")

    def pos(ds, t):
        i = int(np.argmin(np.abs(ds["time"].values - t)))
        return np.stack([ds[c].values[i] for c in ("node_x", "node_y", "node_z")], axis=1), i

    shape_err, vel_err = [], []
    for k, t in enumerate(common):
        xa, ia = pos(traj_small, t)
        xb, ib = pos(traj_large, t)
        shape_err.append(np.linalg.norm(xa - xb, axis=1).max() / np.linalg.norm(xa, axis=1).max())
        if 0 < k < len(common) - 1:
            dt = common[k + 1] - common[k - 1]
            ua = (pos(traj_small, common[k + 1])[0] - pos(traj_small, common[k - 1])[0]) / dt
            ub = (pos(traj_large, common[k + 1])[0] - pos(traj_large, common[k - 1])[0]) / dt
            # induced part only: the background flow is the same in both boxes by construction
            vel_err.append(np.linalg.norm(ua - ub, axis=1).max() / max(np.linalg.norm(ua, axis=1).max(), 1e-300))
    return {"L_small": float(traj_small.attrs.get("L", math.nan)), "L_large": float(traj_large.attrs.get("L", math.nan)),
            "max_shape_error": float(np.max(shape_err)), "max_velocity_error": float(np.max(vel_err)),
            "median_velocity_error": float(np.median(vel_err)), "frames": int(len(common))}


def _run_row(case, traj, spec, theo):
    delta_nominal = float(theo.attrs.get("delta", traj.attrs.get("delta")))
    S = float(theo.attrs.get("S", traj.attrs.get("S")))
    paper = _paper_lstar(delta_nominal, S)
    return {
        "case_id": case["case_id"], "group": case.get("group", "fine"), "delta": delta_nominal,
        "delta_mesh": float(traj.attrs.get("delta", math.nan)), "S": S, "chi": float(traj.attrs.get("chi", math.nan)),
        "N": int(traj.attrs.get("N", -1)), "vertices": int(traj.sizes["n_node"]),
        "family": str(traj.attrs.get("mesh_family", "?")),
        "sim_l_star": float(spec["l_star"]), "sim_l_peak": float(spec.get("l_peak", math.nan)),
        "pa_l_star": float(theo["l_star"]), "pa_l_peak": float(theo.get("l_peak", math.nan)),
        "paper_pa": paper[0] if paper else None, "paper_ibm": paper[1] if paper else None,
        "sim_t_star": float(spec["t_star"]), "pa_t_star": float(theo["t_star"]),
        "growth_decades": stage1_growth(spec),
        "max_area_drift": float(np.abs(traj["area_drift"].values).max()),
        "max_volume_drift": float(np.abs(traj["volume_drift"].values).max()),
        "dt_gamma": float(traj.attrs.get("dt_gamma", math.nan)), "steps": int(traj.attrs.get("steps", -1)),
        "wall_s": float(traj.attrs.get("wall_time_s_last_call", math.nan)),
        "scheme": str(traj.attrs.get("scheme", "?")),
        "defect_ratio": float(spec.get("defect_amplitude_ratio", math.nan)),
    }


def collect(manifest) -> dict:
    import xarray as xr

    rows = []
    for case in manifest["cases"]:
        with xr.open_dataset(case["trajectory"]) as traj, xr.open_dataset(case["spectra"]) as spec, \
                xr.open_dataset(case["theory"]) as theo:
            rows.append(_run_row(case, traj.load(), spec.load(), theo.load()))
    fits = {}
    for group, path in (manifest.get("fits") or {}).items():
        with xr.open_dataset(path) as f:
            fits[group] = f.load()
    box = None
    if manifest.get("box"):
        with xr.open_dataset(manifest["box"]["small"]) as a, xr.open_dataset(manifest["box"]["large"]) as b:
            box = box_comparison(a.load(), b.load())
    return {"rows": rows, "fits": fits, "box": box}


def _group_label(g):
    kind = str(g.group_kind.values)
    text = f"{kind}, Delta {float(g.group_delta):.3g}, {int(g.n_cases)} cases"
    if kind == "simulation" and "group_N" in g:
        text += f", N = {int(g.group_N)}, {int(g.group_vertices)} vertices"
    return text


def _table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(_fmt(c) if not isinstance(c, str) else c for c in r) + " |" for r in rows]
    return "\n".join(out)


def render(manifest, data) -> str:
    rows = data["rows"]
    fine = [r for r in rows if r["group"] == "fine"]
    coarse = [r for r in rows if r["group"] == "coarse"]
    md = [f"# {manifest.get('title', 'Validation against the reference paper')}", ""]
    md += ["Generated by the validation workflow (`snakemake --cores 2 all --configfile config/validation.yaml`); "
           "every number below is read from the produced datasets. Resolution: "
           f"{manifest.get('resolution_note', 'see the case ids')}.", ""]
    md += ["## Characteristic wrinkle mode per case", "",
           "`l_*` is eq. (31) at t_* = argmin Delta_2; `l_peak` the dominant mode at t_* (Sec. V.A). "
           "PA: this project's perturbation analysis of the same (Delta, S). Paper: Figs. 3 and 5 (PA, IBM).", ""]
    md.append(_table(
        ["case", "Delta", "S", "chi", "N", "verts", "sim l_*", "sim l_peak", "PA l_*", "PA l_peak", "paper PA", "paper IBM",
         "sim t_*", "PA t_*", "stage-1 growth l>=6 (decades)"],
        [[r["case_id"], r["delta"], r["S"], r["chi"], r["N"], r["vertices"], r["sim_l_star"], r["sim_l_peak"], r["pa_l_star"],
          r["pa_l_peak"], r["paper_pa"], r["paper_ibm"], r["sim_t_star"], r["pa_t_star"], r["growth_decades"]]
         for r in fine]))
    md.append("")
    md += ["## Exponent of l_* against S", ""]
    frows = []
    f = data["fits"].get("fine")
    if f is not None:
        for i in range(f.sizes["group"]):
            g = f.isel(group=i)
            if int(g.n_cases) < 3:
                continue  # single-point groups (box test) and the two-case Delta = 0.997 pair have no fit
            for name in ("l_star", "l_peak"):
                frows.append([_group_label(g), name, float(g[f"{name}_exponent"]), float(g[f"{name}_ci_low"]),
                              float(g[f"{name}_ci_high"])])
    md.append(_table(["series", "l_* definition", "exponent b", "95% low", "95% high"], frows))
    md += ["", f"Paper: IBM {PAPER_EXPONENT_IBM}, PA {PAPER_EXPONENT_PA}; Turitsyn et al.: 1/3.", ""]
    md += ["## Stage-2 tension decay |sigma| ~ t^-a", ""]
    drows = []
    if f is not None:
        for i in range(f.sizes["case"]):
            c = f.isel(case=i)
            S = float(c.S)
            paper = next((v for k, v in PAPER_DECAY.items() if abs(k - S) / k < 0.02), None)
            drows.append([str(c.case_id.values), str(c.kind.values), S, float(c.decay_exponent), float(c.decay_ci_low),
                          float(c.decay_ci_high), paper, str(c.note.values) or ""])
    md.append(_table(["case", "kind", "S", "a", "95% low", "95% high", "paper (IBM)", "note"], drows))
    md += ["", "## Conservation and cost per run", ""]
    md.append(_table(["case", "scheme", "max area drift", "max volume drift", "gamma_dot dt", "steps", "wall time (s)",
                      "defect amplitude ratio"],
                     [[r["case_id"], r["scheme"], r["max_area_drift"], r["max_volume_drift"], r["dt_gamma"], r["steps"],
                       r["wall_s"], r["defect_ratio"]] for r in rows]))
    md.append("")
    if coarse:
        md += ["## Resolution convergence", ""]
        crow = []
        for c in coarse:
            m = next((r for r in fine if abs(r["S"] - c["S"]) < 1e-6 and abs(r["delta"] - c["delta"]) < 1e-6), None)
            if m:
                crow.append([c["S"], f"N={c['N']}, {c['vertices']} v", c["sim_l_star"], c["sim_l_peak"],
                             f"N={m['N']}, {m['vertices']} v", m["sim_l_star"], m["sim_l_peak"], m["pa_l_star"]])
        md.append(_table(["S", "coarse", "l_*", "l_peak", "fine", "l_*", "l_peak", "PA l_*"], crow))
        md.append("")
    if data["box"]:
        b = data["box"]
        md_box_note = ("Velocities are centred differences of the output frames (total velocity, background flow "
                       "included); the median over frames is the robust number, the maximum comes from frames where "
                       "the membrane is nearly at rest.")
        md += ["## Periodic box (Table I)", "",
               f"The same case in boxes L = {_fmt(b['L_small'])} R and {_fmt(b['L_large'])} R (2.5 and 3.5 diameters "
               f"when 5 R and 7 R) at the same grid spacing, {b['frames']} matched frames:", "",
               _table(["max relative shape difference", "max relative velocity difference", "median velocity difference"],
                      [[b["max_shape_error"], b["max_velocity_error"], b["median_velocity_error"]]]),
               "", md_box_note, "",
               "Paper (Table I): shape 1.2e-5 to 1.3e-3, velocity 1.1e-2 to 1.6e-2 (2.5 diameters vs larger).", ""]
    md += ["## Where this project differs from the paper", ""]
    md += discussion(data) + list(manifest.get("discussion", []))
    md.append("")
    if manifest.get("figures"):
        md += ["## Figures", ""]
        for fig in manifest["figures"]:
            md += [f"![{fig['caption']}]({fig['path']})", "", f"*{fig['caption']}*", ""]
    return "\n".join(md) + "\n"


def _pa_exponent(f, delta):
    for i in range(f.sizes["group"]):
        g = f.isel(group=i)
        if str(g.group_kind.values) == "theory" and abs(float(g.group_delta) - delta) < 1e-6:
            return float(g.l_star_exponent)
    return math.nan


def discussion(data) -> list[str]:
    """Statements derived from the numbers (no per-case tuning): how far the simulation l_* sits from the PA,
    and what limits it at this resolution."""
    out = []
    fine = [r for r in data["rows"] if r["group"] == "fine"]
    if not fine:
        return out
    pairs = sorted((r["S"], r["sim_l_star"] / r["pa_l_star"], r["delta"]) for r in fine
                   if r["pa_l_star"] > 0 and math.isfinite(r["sim_l_star"]))
    if pairs:
        text = ", ".join(f"{ratio:.2f} at S = {S:g} (Delta {d:g})" for S, ratio, d in pairs)
        out.append(f"- Simulation l_* (eq. 31) over the PA value of the same case: {text}. The paper's IBM at 512^3 "
                   "found l_* 7-40% *above* its PA at every S. Here the ratio falls with S: above 1 for weak flows, "
                   "below 1 where the PA's l_* approaches what the grid and mesh can carry (docs/solver.md: the rate of "
                   "a mode l relaxes at exp(-(l h / 1.04)^2) of theory with the 4-point kernel).")
    r0 = fine[0]
    if r0["N"] > 0:
        L_box = 5.0
        h = L_box / r0["N"]
        out.append(f"- At N = {r0['N']} (h ~ {h:.3f} R for L = 5 R) the 4-point kernel spreads each force over 4h = "
                   f"{4 * h:.2f} R, so wrinkles shorter than ~4h, i.e. l >~ pi/(2h) = {math.pi / (2 * h):.0f}, are "
                   "damped by the discrete coupling; the paper's 512^3 grid puts that limit near l = 150.")
    growth = [r["growth_decades"] for r in fine if r["delta"] < 0.5]
    if growth:
        out.append(f"- Wrinkles grow in every quasi-spherical case: Delta_l (l >= 6) rises by {min(growth):.1f}-"
                   f"{max(growth):.1f} decades between the reversal and t_*.")
    f = data["fits"].get("fine")
    if f is not None:
        for i in range(f.sizes["group"]):
            g = f.isel(group=i)
            b = float(g.l_star_exponent)
            if str(g.group_kind.values) != "simulation" or not math.isfinite(b):
                continue
            lo = float(g.l_star_ci_low)
            trend = ("l_* grows with S, but more slowly than the PA: at this resolution the largest l_* are capped by "
                     "the grid and the mesh" if lo > 0 else
                     "l_* does not grow significantly with S (the interval includes 0): at this resolution the grid and "
                     "the mesh set the wrinkle scale")
            out.append(f"- Simulated exponent b = {b:.3f} [{lo:.3f}, {float(g.l_star_ci_high):.3f}] "
                       f"({_group_label(g)}) against the paper's IBM {PAPER_EXPONENT_IBM} and this PA's "
                       f"{_pa_exponent(f, float(g.group_delta)):.3f}: {trend}.")
    out.append("- The PA here evaluates eq. (31) in the normalisation sum |u_lm|^2 = 2 that eq. (10) implies; it gives "
               "l_* 8-15% below the paper's published PA values, while the dominant mode l_peak matches them exactly "
               "(theory.py docstring).")
    return out


def write_report(manifest, out_md) -> Path:
    from .io import atomic_write_text

    data = collect(manifest)
    text = render(manifest, data)
    atomic_write_text(text, out_md)
    return Path(out_md)
