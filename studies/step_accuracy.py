"""How far a run is from a dt-converged reference of the same case: the time-step error of a scheme, in the
observables the paper reports.

    python studies/step_accuracy.py REFERENCE_SPECTRA.nc CANDIDATE_SPECTRA.nc [CANDIDATE ...] [--l 3 30]
        [--t-max 0.5]

Each file is a spectra dataset (``vesicle decompose``) of one case; the reference is the same case run with a much
shorter step (issue 48 takes today's forward-Euler step at a quarter of its dt: ``dt_growth`` and ``dt_safety`` / 4).
Per candidate it prints:

- l_* and t_* between frames (``l_star_fit``, ``t_star_fit``), their relative and absolute differences;
- Delta_2(t): the rms over the reference's frames in 0 <= t <= t_max of the relative difference
  (D_c - D_r) / D_r, with the candidate interpolated linearly in log Delta_2 onto the reference's times (the frames
  of two runs of one case coincide; the interpolation only matters where they do not);
- sigma(t): the rms difference over the same frames divided by the rms of the reference's sigma (the tension
  crosses zero after the reversal, so a pointwise relative difference would be undefined there);
- Delta_l(t_*): each run's spectrum at its own t_* (log-linear between the two frames about it), the largest and
  the rms relative difference over l in the range given.

Issue 48's "Same answers" asks for l_* within 1%, t_* within 0.005, Delta_2(t) and sigma(t) within 2% rms, and
Delta_l(t_*) within 5% at l = 3..30.

Feeds docs/explanation/step-limits.md, "Today's step against a dt-converged reference".
"""

from __future__ import annotations

import argparse

import numpy as np
import xarray as xr


def _at(time, values, t):
    """values (time, ...) at time t, linear in log between the two frames about t (values > 0)."""
    time = np.asarray(time, dtype=float)
    j = int(np.clip(np.searchsorted(time, t), 1, len(time) - 1))
    w = (t - time[j - 1]) / (time[j] - time[j - 1])
    lo, hi = np.log(np.asarray(values[j - 1], float)), np.log(np.asarray(values[j], float))
    return np.exp((1.0 - w) * lo + w * hi)


def compare(ref: xr.Dataset, cand: xr.Dataset, l_range=(3, 30), t_max: float = 0.5) -> dict:
    """The differences of ``cand`` from ``ref`` (module docstring); both spectra datasets of one case."""
    tr = np.asarray(ref["time"].values, float)
    tc = np.asarray(cand["time"].values, float)
    sel = (tr >= 0.0) & (tr <= t_max) & (tr >= tc.min()) & (tr <= tc.max())
    if sel.sum() < 2:
        raise SystemExit(f"the runs share fewer than two frames in 0 <= t <= {t_max}")
    t = tr[sel]
    D2r = np.asarray(ref["Delta_l"].sel(l=2).values, float)[sel]
    D2c = np.exp(np.interp(t, tc, np.log(np.asarray(cand["Delta_l"].sel(l=2).values, float))))
    sr = np.asarray(ref["sigma"].values, float)[sel]
    sc = np.interp(t, tc, np.asarray(cand["sigma"].values, float))
    ls = np.arange(l_range[0], l_range[1] + 1)
    star = {}
    for name, ds in (("ref", ref), ("cand", cand)):
        ts = float(ds["t_star_fit"])
        star[name] = (ts, float(ds["l_star_fit"]),
                      _at(ds["time"].values, np.asarray(ds["Delta_l"].sel(l=ls).values, float), ts))
    rel_l = star["cand"][2] / star["ref"][2] - 1.0
    return {
        "frames": int(sel.sum()),
        "l_star_ref": star["ref"][1], "l_star": star["cand"][1],
        "l_star_rel": star["cand"][1] / star["ref"][1] - 1.0,
        "t_star_ref": star["ref"][0], "t_star": star["cand"][0],
        "t_star_diff": star["cand"][0] - star["ref"][0],
        "delta2_rms_rel": float(np.sqrt(np.mean((D2c / D2r - 1.0) ** 2))),
        "sigma_rms_rel": float(np.sqrt(np.mean((sc - sr) ** 2)) / np.sqrt(np.mean(sr ** 2))),
        "delta_l_max_rel": float(np.max(np.abs(rel_l))),
        "delta_l_rms_rel": float(np.sqrt(np.mean(rel_l ** 2))),
        "delta_l_worst_l": int(ls[int(np.argmax(np.abs(rel_l)))]),
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("reference", help="spectra.nc of the dt-converged run")
    p.add_argument("candidates", nargs="+", help="spectra.nc of the runs to compare with it")
    p.add_argument("--l", type=int, nargs=2, default=(3, 30), metavar=("L_MIN", "L_MAX"),
                   help="degrees of the Delta_l(t_*) comparison (default 3 30)")
    p.add_argument("--t-max", type=float, default=0.5, help="last time of the Delta_2 and sigma comparison, "
                   "gamma_dot (t - t0) (default 0.5)")
    args = p.parse_args(argv)
    if not 2 <= args.l[0] <= args.l[1]:
        p.error(f"--l: need 2 <= L_MIN <= L_MAX, got {args.l}")
    with xr.open_dataset(args.reference) as ref:
        ref = ref.load()
    print(f"reference: {args.reference}: l_* = {float(ref['l_star_fit']):.3f}, t_* = {float(ref['t_star_fit']):.4f}")
    print("| candidate | l_* | vs ref | t_* | vs ref | Delta_2(t) rms | sigma(t) rms | Delta_l(t_*) max (l) | "
          "Delta_l(t_*) rms | frames |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for path in args.candidates:
        with xr.open_dataset(path) as cand:
            r = compare(ref, cand.load(), tuple(args.l), args.t_max)
        print(f"| {path} | {r['l_star']:.3f} | {100 * r['l_star_rel']:+.2f}% | {r['t_star']:.4f} | "
              f"{r['t_star_diff']:+.4f} | {100 * r['delta2_rms_rel']:.2f}% | {100 * r['sigma_rms_rel']:.2f}% | "
              f"{100 * r['delta_l_max_rel']:.1f}% ({r['delta_l_worst_l']}) | {100 * r['delta_l_rms_rel']:.1f}% | "
              f"{r['frames']} |")


if __name__ == "__main__":
    main()
