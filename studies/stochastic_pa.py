"""Stochastic PA report: l_*, l_peak and t_* over seeds, against the deterministic PA, for kT, l_max, grid, step.

    python studies/stochastic_pa.py [--seeds 16] [--steps 4000] > numbers.md

Delta = 0.116, S = 553 and 2224 (the paper's quasi-spherical pair). Rows (each over the same ``--seeds`` seeds):

* ``PA`` -- theory.solve, the deterministic PA from the literal thermal start (the project's default PA), at the
  three kT;
* ``start`` -- the stochastic PA's equilibrium start, deterministic after the reversal (noise="start");
* ``on`` -- noise on throughout, at kT/kappa = 0.00405, 0.0405, 0.405 (x0.1, x1, x10);
* the truncation l_max (every mode fluctuates, so l_max is an input: 20, 30, default, 1.5 x default);
* the grid: the rates damped by theory.grid_damping for h = 5/128 (128^3 in a 5 R box), kernel and sharp coupling;
* the step: 2 x ``--steps``.

Then the equilibrium spectrum of the free vesicle (S = 0, Delta = 0.04, l_max = 16, ``--equilibrium-seeds`` seeds,
2 tau each after a burn-in of 0.1 tau) at two steps:
measured <|u_lm|^2> over kT / (kappa Delta [l(l+1) + <sigma>]), and the exact fixed-area ensemble (rejection
sampling) over the same formula at the mean-field tension: what the constraint alone does to the spectrum.

Feeds docs/history/thermal.md, "6. The stochastic PA: eqs. (11)-(12) with their thermal forcing".
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from vesicle_core.analysis import stochastic_pa as SP
from vesicle_core.analysis import theory as T
from vesicle_core.model.modes import default_l_max

KT = 0.0405
DELTA = 0.116


def _row(label, run, seconds):
    s = run.summary()
    return (f"| {run.S:g} | {label} | {run.kT_over_kappa:g} | {run.l_max} | {s['l_star']:.2f} +- {s['l_star_sd']:.2f} "
            f"| {s['l_peak']:.1f} +- {s['l_peak_sd']:.1f} | {s['t_star']:.4f} +- {s['t_star_sd']:.4f} "
            f"| {np.min(run.l_star):.2f} - {np.max(run.l_star):.2f} | {seconds:.0f} |")


def _timed(**kw):
    t0 = time.perf_counter()
    run = SP.simulate(DELTA, **kw)
    return run, time.perf_counter() - t0


def wrinkling(seeds, steps):
    print("| S | run | kT/kappa | l_max | l_* (eq. 31) mean +- sd | l_peak mean +- sd | t_* mean +- sd | l_* range "
          "| s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for S in (553.0, 2224.0):
        L = default_l_max(S)
        for k in (KT / 10, KT, KT * 10):
            ref = T.solve(DELTA, S, kT_over_kappa=k)
            print(f"| {S:g} | PA (deterministic, literal thermal start) | {k:g} | {ref.l_max} | {ref.l_star:.2f} "
                  f"| {ref.l_peak:.0f} | {ref.t_star:.4f} | - | - |", flush=True)
        rows = [("start (equilibrium start, no noise after)", dict(noise="start"))]
        rows += [("on", dict(kT_over_kappa=k)) for k in (KT / 10, KT, KT * 10)]
        rows += [("on, l_max", dict(l_max=lm)) for lm in (20, 30, int(1.5 * L))]
        rows += [(f"on, grid 128^3 {c}", dict(grid_h=5 / 128, coupling=c)) for c in ("kernel", "sharp")]
        rows += [("on, 2 x steps", dict(n_steps=2 * steps))]
        for label, kw in rows:
            kw = {"S": S, "seeds": seeds, "n_steps": steps, "kT_over_kappa": KT, **kw}
            run, sec = _timed(**kw)
            print(_row(label, run, sec), flush=True)
            if label == "on" and run.kT_over_kappa == KT:
                print(f"<!-- S={S:g} l_star per seed: {np.round(run.l_star, 2).tolist()} -->", flush=True)


def equilibrium_table(n_seeds, n_steps=10000):
    print()
    print("| ds | <sigma> | mean-field sigma | sd(sigma) per step | ratio l = 2 | 3 | 4 | 6 | 8 | 12 | 16 | max se |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    # other seeds at the second step: the same seeds would draw the same deviates and correlate the two rows
    for first, ds, n in ((0, 2e-4, n_steps), (n_seeds, 1e-4, 2 * n_steps)):
        eq = SP.equilibrium(0.04, l_max=16, seeds=range(first, first + n_seeds), ds=ds, n_steps=n,
                            burn_in=min(int(0.1 / ds), n // 2),  # 0.1 tau, or half of a short row
                            kT_over_kappa=KT)
        th = SP.equilibrium_variance(eq["l"][2:], eq["sigma_mean"], 0.04, KT)
        ratio = dict(zip(range(2, 17), eq["var"][2:] / th, strict=True))
        se = np.max(eq["var_se"][2:] / th)
        cols = " | ".join(f"{ratio[l]:.3f}" for l in (2, 3, 4, 6, 8, 12, 16))
        print(f"| {ds:g} | {eq['sigma_mean']:.2f} | {eq['sigma_mean_field']:.2f} | {eq['sigma_sd']:.1f} | {cols} "
              f"| {se:.3f} |", flush=True)


def constrained_reference(draws=4_000_000, width=0.01, seed=5):
    """The exact fixed-area ensemble by rejection: Gaussian draws at the mean-field tension kept when
    |sum |u|^2 - 2| < width (the constrained measure does not depend on the tension the draws use)."""
    t = SP.ModeTable.build(16)
    sig, _ = SP.mean_field_tension(0.04, 0.0, 16, KT)
    var = SP.equilibrium_variance(t.l, sig, 0.04, KT)
    rng = np.random.default_rng(seed)
    acc, n = np.zeros(17), 0
    for _ in range(draws // 20000):
        z = rng.standard_normal((2, 20000, t.l.size))
        u = np.where(t.m == 0, z[0], (z[0] + 1j * z[1]) / np.sqrt(2.0)) * np.sqrt(var)
        keep = np.abs((t.w * np.abs(u) ** 2).sum(-1) - 2.0) < width
        acc += t.delta_l(u[keep]).sum(0)
        n += int(keep.sum())
    ratio = (acc / n / (2 * np.arange(17) + 1))[2:] / SP.equilibrium_variance(np.arange(2, 17), sig, 0.04, KT)
    cols = " | ".join(f"{ratio[l - 2]:.3f}" for l in (2, 3, 4, 6, 8, 12, 16))
    print(f"| exact fixed-area ensemble ({n} accepted draws) | - | {sig:.2f} | - | {cols} | "
          f"{np.sqrt(2 / (5 * n)):.4f} |", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--equilibrium-seeds", type=int, default=64)
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--equilibrium-steps", type=int, default=10000, help="steps of the first equilibrium row "
                    "(the second, at half the step, takes twice as many)")
    ap.add_argument("--draws", type=int, default=4_000_000, help="Gaussian draws of the fixed-area ensemble")
    ap.add_argument("--skip-equilibrium", action="store_true")
    a = ap.parse_args(argv)
    wrinkling(tuple(range(a.seeds)), a.steps)
    if not a.skip_equilibrium:
        equilibrium_table(a.equilibrium_seeds, a.equilibrium_steps)
        constrained_reference(a.draws)


if __name__ == "__main__":
    main()
