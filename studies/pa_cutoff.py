"""Exponent of the PA's l_* ~ S^b (eq. 31, Fig. 4) against the mode cutoff l_max, at Delta = 0.116.

    python benchmarks/pa_cutoff.py [--config config/validation.yaml] [--l-max 16 20 ... 64 default] [--csv out.csv]

Tests the hypothesis that the paper's PA exponent 0.372 (this PA: 0.430) comes from a truncated mode expansion.
The S sets are read from the config's quasi-spherical sweep group: its ``S`` (the paper's five IBM cases), its
``pa_S`` (the wider PA-only range) and their union (the 13 theory cases behind the validation report's b).
Per l_max it prints b with its 95 % interval, l_* (eq. 31) and l_peak at S = 553 and 2224 (the paper's published
PA values there are 14 and 25, matched by l_peak), r2 of the log-log fit (an active cutoff bends the curve) and
the S at which the cutoff is active (modes at l_max are nontrivial at t_*). One process, no threads: each PA solve
takes ~0.04 s of CPU, the default run ~10 s.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import csv
import sys
import time
from pathlib import Path

import yaml

from vesicle_core.validation.cutoff import DEFAULT_LMAX_LABEL, exponent_vs_lmax

DELTA = 0.116
L_MAX = [16, 20, 24, 28, 32, 36, 40, 48, 64, None]
# the published PA exponent (Fig. 4) and the published PA l_* (Fig. 3 caption) the columns are read against
PAPER_B = 0.372
PROBE_S = (553.0, 2224.0)


def s_sets(config_path, delta):
    """The (name, S values) to fit, from the config group with this delta that has pa_S."""
    cfg = yaml.safe_load(Path(config_path).read_text())
    group = next((g for g in cfg["sweep"] if abs(float(g["delta"]) - delta) < 1e-9 and g.get("pa_S")), None)
    if group is None:
        sys.exit(f"{config_path}: no sweep group with delta = {delta} and pa_S")
    paper = sorted(float(s) for s in group["S"])
    pa = sorted(float(s) for s in group["pa_S"])
    return [("paper S (IBM cases)", paper), ("pa_S", pa), ("union", sorted(set(paper) | set(pa)))]


def _lmax_arg(text):
    return None if text == "default" else int(text)


def _label(L):
    return "default" if L == DEFAULT_LMAX_LABEL else str(L)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", default="config/validation.yaml", help="config with the sweep's S and pa_S")
    p.add_argument("--delta", type=float, default=DELTA)
    p.add_argument("--l-max", nargs="+", type=_lmax_arg, default=L_MAX,
                   help="cutoffs; 'default' = theory.default_l_max(S)")
    p.add_argument("--csv", help="also write the table as CSV to this path")
    a = p.parse_args(argv)

    sets = s_sets(a.config, a.delta)
    cpu = time.process_time()
    results = {name: exponent_vs_lmax(a.delta, S, a.l_max) for name, S in sets}
    cpu = time.process_time() - cpu
    n_solves = sum(ds.sizes["l_max"] * ds.sizes["S"] for ds in results.values())
    # l_* at a given S does not depend on which S set is fitted: read the probes from the union
    union = results[sets[-1][0]]

    def probe(var, L, s):
        return float(union[var].sel(l_max=L, S=s)) if s in union["S"].values else float("nan")

    rows = []
    for name, S in sets:
        ds = results[name]
        for L in ds["l_max"].values:
            d = ds.sel(l_max=L)
            active = [s for s, t in zip(ds["S"].values, d["truncated"].values, strict=True) if t]
            rows.append({
                "S_set": name, "n_S": len(S), "l_max": _label(L),
                "b": float(d.b), "b_low": float(d.b_low), "b_high": float(d.b_high),
                "prefactor": float(d.prefactor), "r2": float(d.r2), "l_peak_b": float(d.l_peak_b),
                **{f"l_star_{s:g}": probe("l_star", L, s) for s in PROBE_S},
                **{f"l_peak_{s:g}": probe("l_peak", L, s) for s in PROBE_S},
                "paper_b_inside": bool(d.b_low <= PAPER_B <= d.b_high),
                "truncated_at_S": " ".join(f"{s:g}" for s in active) or "-",
            })

    for name, S in sets:
        print(f"\nDelta = {a.delta}, {name}: S = {', '.join(f'{s:g}' for s in S)}")
        print(f"{'l_max':>7}  {'b [95% interval]':<24} {'l_* 553':>8} {'l_* 2224':>8} {'peak 553':>8} "
              f"{'peak 2224':>9} {'b(l_peak)':>9} {'r2':>6}  truncation active at S")
        for r in (r for r in rows if r["S_set"] == name):
            mark = "*" if r["paper_b_inside"] else " "
            print(f"{r['l_max']:>7}  {r['b']:.3f} [{r['b_low']:.3f}, {r['b_high']:.3f}]{mark}"
                  f"     {r['l_star_553']:8.2f} {r['l_star_2224']:8.2f} {r['l_peak_553']:8.0f} {r['l_peak_2224']:9.0f} "
                  f"{r['l_peak_b']:9.3f} {r['r2']:6.4f}  {r['truncated_at_S']}")
    print(f"\n* the paper's PA exponent {PAPER_B} lies inside the interval. Paper's PA l_* at 553, 2224: 14, 25.")
    print(f"{n_solves} PA solves in {cpu:.1f} s CPU ({cpu / n_solves:.3f} s per solve)")

    if a.csv:
        with open(a.csv, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        print(f"wrote {a.csv}")
    return rows


if __name__ == "__main__":
    main()
