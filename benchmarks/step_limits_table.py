"""What set the steps of finished runs: a Markdown table from their trajectories (docs/explanation/step-limits.md).

    python benchmarks/step_limits_table.py results/runs/<case>/trajectory.nc [...] > table.md

Per run: the steps, their shares by the limit that set them (the per-frame ``steps_<limit>`` counts), the Stokes
solves (and the bending limit's and the thermal drift's, which ``stokes_solves`` counts or leaves out as
docs/reference/datasets.md says), the wall time, and the median allowed step of each limit after the reversal
against the step taken there. With the run's spectra.nc beside the trajectory, also l_* and t_* at the frame and
between the frames.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import xarray as xr

from vesicle_core.solver.step_limits import LIMITS, shares_line


def row(path: Path) -> dict:
    with xr.open_dataset(path) as ds:
        ds.load()
    counts = {k: int(ds[f"steps_{k}"].sum()) for k in LIMITS if f"steps_{k}" in ds}
    after = ds.time.values > 0
    med = {k: float(np.nanmedian(ds[f"dt_limit_{k}"].values[after])) for k in LIMITS
           if f"dt_limit_{k}" in ds and np.isfinite(ds[f"dt_limit_{k}"].values[after]).any()}
    at = ds.attrs
    out = {"case": at.get("case_id", path.parent.name), "steps": int(at["steps"]), "shares": shares_line(counts),
           "stokes": int(at.get("stokes_solves", -1)), "bending_solves": int(at.get("bending_solves", -1)),
           "thermal_solves": int(at.get("thermal_stokes_solves", 0)), "wall": float(at.get("wall_time_s", np.nan)),
           "stokes_share": float(at.get("stokes_s", np.nan)) / float(at.get("wall_time_s_last_call", np.nan)),
           "dt_median": med, "dt_taken": float(np.median(ds.dt_tau.values[after]))}
    spec = path.with_name("spectra.nc")
    if spec.exists():
        with xr.open_dataset(spec) as sp:
            out.update({k: float(sp[k]) for k in ("l_star", "t_star", "l_star_fit", "t_star_fit") if k in sp})
    return out


def main(paths):
    rows = [row(Path(p)) for p in paths]
    print("| case | steps | shares by limit | Stokes solves (bending limit's; thermal drift's) | wall time, s "
          "| Stokes products' share |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['steps']} | {r['shares'].split('(')[-1].rstrip(')')} | {r['stokes']} "
              f"({r['bending_solves']}; {r['thermal_solves']}) | {r['wall']:.0f} | {100 * r['stokes_share']:.0f}% |")
    print()
    print("Median step each limit allowed after the reversal, and the median step taken there (tau):")
    print()
    names = [k for k in LIMITS if any(k in r["dt_median"] for r in rows)]
    print("| case | " + " | ".join(names) + " | taken |")
    print("|---|" + "---|" * (len(names) + 1))
    for r in rows:
        cells = [f"{r['dt_median'][k]:.3g}" if k in r["dt_median"] else "-" for k in names]
        print(f"| {r['case']} | " + " | ".join(cells) + f" | {r['dt_taken']:.3g} |")
    if any("l_star" in r for r in rows):
        print()
        print("| case | t_* (frame) | l_* (frame) | t_* (between frames) | l_* (between frames) |")
        print("|---|---|---|---|---|")
        for r in rows:
            if "l_star" in r:
                print(f"| {r['case']} | {r['t_star']:.3f} | {r['l_star']:.2f} | {r.get('t_star_fit', np.nan):.4f} "
                      f"| {r.get('l_star_fit', np.nan):.2f} |")


if __name__ == "__main__":
    main(sys.argv[1:])
