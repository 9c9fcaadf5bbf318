"""Wrinkling with noise in the IBM: the ensemble's l_*, l_peak and t_* against the deterministic run of the same
discretisation, the stochastic PA and the deterministic PA on the same grid, and the cost of the noise.

    snakemake --cores 2 results/fits/lstar_vs_S.nc results/catalog.csv --configfile config/thermal.yaml
    python studies/thermal_ensemble.py results/catalog.csv [--kT 0.0405] [--pa-seeds 16] > numbers.md

The IBM numbers come from the catalog through ``open_sweep`` (the ensemble stacked along ``noise_seed``, the
deterministic runs selected by kT = 0). The PA rows use the runs' grid (h = L/N, their kernel and coupling, through
theory.grid_damping) and the spectra's l_max, so that eq. (31) sums over the same modes (docs/history/thermal.md,
section 6: under noise l_* depends on l_max). The cost columns read each trajectory's attributes: wall time, steps,
Stokes solves of the main tension solve and of the noise (field and drift).

Feeds docs/history/thermal.md, "8. Wrinkling with noise in the IBM: an ensemble in the workflow".
"""

from __future__ import annotations

import argparse

import numpy as np
import xarray as xr

from vesicle_core.analysis import stochastic_pa as SP
from vesicle_core.analysis import theory as T
from vesicle_core.data.sweep import open_sweep


def _paths(values):
    """The files of a stacked selection; an ensemble with fewer seeds at one S has NaN paths there (outer join)."""
    return [str(p) for p in np.ravel(values) if isinstance(p, str) and p not in ("", "nan")]


def _cost(paths):
    out = []
    for p in _paths(paths):
        with xr.open_dataset(str(p).replace("spectra.nc", "trajectory.nc")) as tr:
            a = tr.attrs
            out.append((float(a["wall_time_s"]), int(a["steps"]), int(a["stokes_solves"]),
                        int(a.get("thermal_stokes_solves", 0))))
    return np.array(out, dtype=float)


def _grid(ds):
    with xr.open_dataset(_paths(ds.path.values)[0]) as sp:
        a = sp.attrs
        return (float(a["L"]) / int(a["N"]), str(a.get("kernel", "peskin4")), str(a.get("coupling", "kernel")),
                int(sp.sizes["l"]) - 1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("catalog")
    ap.add_argument("--kT", type=float, default=0.0405)
    ap.add_argument("--pa-seeds", type=int, default=16)
    a = ap.parse_args()
    hot = open_sweep(a.catalog, kT=a.kT)
    cold = open_sweep(a.catalog, kT=0)
    h, kernel, coupling, l_max = _grid(hot)
    print(f"grid h = {h:.4g} R, {kernel}, {coupling} coupling; spectra l_max = {l_max}; kT/kappa = {a.kT:g}")
    print()
    print("| S | source | n | l_* (eq. 31) mean +- sd | range | l_peak mean +- sd | t_* mean +- sd |")
    print("|---|---|---|---|---|---|---|")
    for delta in hot.Delta.values:
        for S in hot.S.values:
            e = hot.sel(Delta=delta, S=S)
            ls, lp, ts = (np.asarray(e[v].values, float) for v in ("l_star", "l_peak", "t_star"))
            ok = np.isfinite(ls)
            c = cold.sel(Delta=delta, S=S)
            print(f"| {S:g} | IBM, deterministic | 1 | {float(c.l_star):.2f} | - | {float(c.l_peak):.0f} | "
                  f"{float(c.t_star):.3f} |")
            print(f"| {S:g} | IBM, noise on | {ok.sum()} | {ls[ok].mean():.2f} +- {ls[ok].std(ddof=1):.2f} | "
                  f"{ls[ok].min():.2f} - {ls[ok].max():.2f} | {lp[ok].mean():.1f} +- {lp[ok].std(ddof=1):.1f} | "
                  f"{ts[ok].mean():.3f} +- {ts[ok].std(ddof=1):.3f} |")
            ref = T.solve(float(delta), float(S), grid_h=h, kernel=kernel, coupling=coupling)
            print(f"| {S:g} | PA on the grid, deterministic (literal start) | 1 | {ref.l_star:.2f} | - | "
                  f"{ref.l_peak:.0f} | {ref.t_star:.3f} |")
            for noise in ("start", "on"):
                run = SP.simulate(float(delta), float(S), seeds=range(a.pa_seeds), kT_over_kappa=a.kT, l_max=l_max,
                                  noise=noise, grid_h=h, kernel=kernel, coupling=coupling)
                s = run.summary()
                print(f"| {S:g} | stochastic PA on the grid, noise {noise} | {a.pa_seeds} | {s['l_star']:.2f} +- "
                      f"{s['l_star_sd']:.2f} | {np.min(run.l_star):.2f} - {np.max(run.l_star):.2f} | "
                      f"{s['l_peak']:.1f} +- {s['l_peak_sd']:.1f} | {s['t_star']:.3f} +- {s['t_star_sd']:.3f} |",
                      flush=True)
    print()
    print("| S | runs | wall [s] median | steps median | Stokes solves per step (main + noise) | wall ratio |")
    print("|---|---|---|---|---|---|")
    for S in hot.S.values:
        ch = _cost(np.ravel(hot.sel(S=S).path.values))
        cc = _cost(np.ravel(cold.sel(S=S).path.values))
        for name, c in (("deterministic", cc), ("noise on", ch)):
            per = (c[:, 2] + c[:, 3]) / c[:, 1]
            print(f"| {S:g} | {name} ({len(c)}) | {np.median(c[:, 0]):.0f} | {np.median(c[:, 1]):.0f} | "
                  f"{np.median(c[:, 2] / c[:, 1]):.1f} + {np.median(c[:, 3] / c[:, 1]):.1f} = {np.median(per):.1f} | "
                  f"{np.median(c[:, 0]) / np.median(cc[:, 0]):.2f} |")


if __name__ == "__main__":
    main()
