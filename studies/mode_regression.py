"""Onsager regression at equilibrium: the noisy run's mode autocorrelation times against the deterministic
relaxation of the same discretisation, started from the run's own frames.

    python studies/mode_regression.py TRAJECTORY.nc [--starts 4] [--span 0.006] [--l-max 16] > numbers.md

TRAJECTORY is a noisy run without flow at a fixed tension (``tension_fixed``, chi = 0, kT > 0; docs/history/thermal.md
section 7). ``--starts`` frames from its second half are each taken as the start of a run with the trajectory's own
parameters but kT = 0 and the explicit midpoint step (second order, ``noise_scheme: midpoint``; forward Euler's
decay is itself O(a dt) fast), frames every step, for ``--span`` tau. In the linear regime the mean deterministic
decay of an equilibrium state's modes is their equilibrium autocorrelation function (Onsager's regression
hypothesis), so per l:

* C_l(t) = sum_m Re[d_lm(t) d_lm(0)^*] / sum_m |d_lm(0)|^2 with d = u - <u> (the noisy run's mean over the same
  frames as its autocorrelation: a mesh's irregularity puts a static part into the high l), summed over the starts,
  and its 1/e time (interpolated);
* the noisy run's autocorrelation time of Re/Im u_lm, m > 0, by the definition of ``thermal_equilibrium.py``
  (burn-in 30%), and the ratio of the two. Both interpolate linearly between frames, which lengthens a time that
  spans only a few frames: make the noisy run's frames dense (every 1-2 steps).

This tests "mode autocorrelation times equal to the same grid's deterministic relaxation" with the membrane, tension
space, ALE, mesh and coupling of the run itself, where ``thermal_equilibrium.py`` compares with the clean interface's
rate ratio r_l of the resolution table.

Feeds docs/history/thermal.md, "The sharp coupling at equilibrium: spectrum and mode times (2026-12-07)" (Onsager
regression).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from dataclasses import replace

import numpy as np
import xarray as xr

from vesicle_core.geometry.mesh import Mesh
from vesicle_core.model.run_config import RunConfig
from vesicle_core.solver.simulate import run

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from thermal_equilibrium import corr_time, spectra  # noqa: E402


def run_config(ds, **override) -> RunConfig:
    """The trajectory's run parameters, with ``override``."""
    return replace(RunConfig.from_attrs(ds.attrs), **override)


def decay(ds, frame, span, l_max, delta, workdir):
    """u_lm(t) (frames, l, m) of a deterministic run from frame ``frame`` of ds, frames every step."""
    f = ds.face_node_connectivity.values
    X = np.stack([ds.node_x.values[frame], ds.node_y.values[frame], ds.node_z.values[frame]], -1).astype(float)
    dt = float(ds.attrs["dt_tau"])
    # the explicit midpoint (RK2): forward Euler's own decay per step, 1 - a dt against exp(-a dt), is 13% fast at
    # a dt = 0.25, which the fast modes of a noise-limited step reach; the midpoint's is within 1% there
    cfg = run_config(ds, kT=0.0, t_end=span, output_every=dt, dt=dt, stretch=0.0, noise_scheme="midpoint")
    out = run(Mesh(X, f.astype(np.int64), {}), cfg, os.path.join(workdir, f"start{frame}"), progress=False)
    det = xr.open_dataset(out)
    return det.t_tau.values - det.t_tau.values[0], spectra(det, l_max, delta, 0)


def one_over_e(t, c):
    below = np.flatnonzero(c < np.exp(-1))
    if not below.size:
        return np.nan
    j = below[0]
    return t[j - 1] + (c[j - 1] - np.exp(-1)) / (c[j - 1] - c[j]) * (t[j] - t[j - 1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("trajectory")
    ap.add_argument("--starts", type=int, default=4, help="deterministic runs, from frames of the second half")
    ap.add_argument("--span", type=float, default=0.006, help="length of each deterministic run [tau]")
    ap.add_argument("--l-max", type=int, default=16)
    a = ap.parse_args()
    ds = xr.open_dataset(a.trajectory).load()
    delta = float(ds.attrs.get("mesh_target_delta", ds.attrs["delta"]))  # as thermal_equilibrium.py
    n = ds.sizes["time"]
    starts = np.linspace(n // 2, n - 1, a.starts).astype(int)
    noisy = spectra(ds, a.l_max, delta, int(0.3 * n))
    mean = noisy.mean(axis=0)  # the regression is of the fluctuations about the equilibrium mean
    num = den = None
    with tempfile.TemporaryDirectory() as work:
        for k in starts:
            t, u = decay(ds, int(k), a.span, a.l_max, delta, work)
            u = u - mean
            c = np.real(u * np.conj(u[:1])).sum(-1)  # (frames, l)
            num = c if num is None else num + c
            den = c[0] if den is None else den + c[0]
    C = num / den
    dt_frames = float(np.median(np.diff(ds.t_tau.values)))
    L = a.l_max
    print(f"run: {a.trajectory}; {a.starts} deterministic runs of {a.span:g} tau (frames every step) from frames "
          f"{', '.join(str(int(k)) for k in starts)}; kT = 0 and the midpoint step, otherwise its parameters")
    print()
    print("| l | deterministic 1/e time [tau] | noisy autocorrelation time [tau] | noisy / deterministic |")
    print("|---|---|---|---|")
    for l in range(2, L + 1):
        t_det = one_over_e(t, C[:, l])
        comps = np.concatenate([noisy[:, l, L + 1:L + 1 + l].real, noisy[:, l, L + 1:L + 1 + l].imag], axis=1)
        t_noisy = corr_time(comps, dt_frames, max(4, noisy.shape[0] // 4))
        print(f"| {l} | {t_det:.4g} | {t_noisy:.4g} | {t_noisy / t_det:.3f} |")


if __name__ == "__main__":
    main()
