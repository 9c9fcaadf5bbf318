"""Growth rate per l in time windows after the reversal: where two runs of a ladder part.

    python studies/growth_windows.py SPECTRA.nc [SPECTRA.nc ...] [--windows 0 0.04 0.08 0.12 0.16] [--l 16 20 ...]

Each file is a spectra dataset (``vesicle decompose``) or a PA solution (``vesicle theory``): both carry time
(gamma_dot (t - t0)), Delta_l (time, l) and sigma (time). For each window [a, b] it prints the mean rate
ln(Delta_l(b) / Delta_l(a)) / (b - a) per l, in units of gamma_dot (the frames nearest a and b), and the mean
tension over the frames inside the window. A linear mode's rate is set by the tension and the bending at its l;
two rungs whose rates agree in the first window and part later differ in the nonlinear stage, not in the linear
operator (docs/history/solver.md, "Wrinkling ladders with the sharp coupling").

Feeds docs/history/solver.md, "Wrinkling ladders with the sharp coupling" (where two rungs part, in time).
"""

from __future__ import annotations

import argparse
from itertools import pairwise

import numpy as np
import xarray as xr

DEFAULT_L = [16, 20, 24, 28, 30, 32, 34, 36, 40, 44, 48]
DEFAULT_WINDOWS = [0.0, 0.04, 0.08, 0.12, 0.16]


def window_rates(time, Delta_l, sigma, windows, ls):
    """Rows (a, b, mean sigma over [a, b], rates per l) for consecutive window edges; Delta_l (time, l)."""
    time = np.asarray(time, dtype=float)
    rows = []
    for a, b in pairwise(windows):
        i, j = int(np.argmin(np.abs(time - a))), int(np.argmin(np.abs(time - b)))
        if j <= i:
            raise SystemExit(f"window [{a}, {b}] holds no two distinct frames (frames every "
                             f"{np.median(np.diff(time)):.3g})")
        inside = (time >= time[i]) & (time <= time[j])
        rates = [float(np.log(Delta_l[j, l] / Delta_l[i, l]) / (time[j] - time[i])) for l in ls]
        rows.append((float(time[i]), float(time[j]), float(np.mean(np.asarray(sigma)[inside])), rates))
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="+")
    p.add_argument("--windows", type=float, nargs="+", default=DEFAULT_WINDOWS,
                   help="window edges in gamma_dot (t - t0), increasing")
    p.add_argument("--l", type=int, nargs="+", default=DEFAULT_L, help="degrees to print")
    args = p.parse_args(argv)
    if len(args.windows) < 2 or any(b <= a for a, b in pairwise(args.windows)):
        p.error("--windows: at least two edges, strictly increasing")
    for f in args.files:
        with xr.open_dataset(f) as ds:
            lmax = ds.sizes["l"] - 1
            ls = [l for l in args.l if 0 <= l <= lmax]
            rows = window_rates(ds["time"].values, ds["Delta_l"].values, ds["sigma"].values, args.windows, ls)
            lstar = float(ds["l_star"]) if "l_star" in ds else float("nan")
        print(f"\n{f}: l_* {lstar:.2f}; rate ln(Delta_l(b) / Delta_l(a)) / (b - a) [gamma_dot]")
        print("| window | mean sigma | " + " | ".join(f"l = {l}" for l in ls) + " |")
        print("|---|---|" + "---|" * len(ls))
        for a, b, s, rates in rows:
            print(f"| {a:.2f}-{b:.2f} | {s:.0f} | " + " | ".join(f"{r:.1f}" for r in rates) + " |")


if __name__ == "__main__":
    main()
