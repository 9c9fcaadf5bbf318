"""Diffusion of free markers under the thermal noise alone, against Hasimoto, and the size of the Ito drift div M.

    python studies/thermal_diffusion.py [--steps 4000] [--N 16 32] > numbers.md

For each grid N (box L = N h, h = 1, kT = 1, mu = 1) and coupling (kernel: Peskin 4-point; sharp: the window
deconvolution at floor 0.01), ``--markers`` passive markers start on a lattice (spacing L / 2) and move by
Euler-Maruyama in the fixed grid frame, X <- X + J(X) dU with dU the noise field of
:class:`vesicle_core.solver.fluctuations.ThermalNoise` (no forces, no drift term). Measured:

* D_inc = <|dX|^2> / (6 dt) over every marker and step (the one-step covariance, 2 kT dt M_self(X));
* D_msd = MSD(tau) / (6 tau) at a lag tau (unwrapped positions), the long-time diffusion coefficient;
  error bars: the std of block means (time blocks, markers averaged inside a block) / sqrt(blocks);
* kT <M_self>: the self-mobility averaged over 64 random sub-grid positions (3 unit forces each);
* D_H = kT / (6 pi R_h) [1 - 2.837297 x + (4 pi / 3) x^3 - 27.4 x^6], x = R_h / L, with R_h from
  ``stokeslet.hydrodynamic_radius`` (N = 64, Hasimoto-corrected self-mobility);
* |div M| (the Ito drift / kT) in units of M_self / h, at N = 16: one marker at 32 random positions; every vertex
  of an icosphere of radius 4 h (162 vertices, edges ~1.2 h) at 4 random sub-grid shifts, and the per-vertex mean
  over the shifts (the systematic part) with its radial component; next to it the self-mobility's relative spread
  over sub-grid positions (the kernel's translation-invariance error).

Feeds docs/explanation/thermal-noise.md, "3. Diffusion of a free marker in the periodic box, and the Ito drift".
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from vesicle_core.solver.backend import get_backend
from vesicle_core.solver.fluctuations import ThermalNoise, mobility_divergence, mobility_matrix
from vesicle_core.solver.ibm import Coupler, Grid
from vesicle_core.solver.kernels import sharpening_symbol
from vesicle_core.solver.mobility import IBMMobility
from vesicle_core.solver.stokes import StokesSolver
from vesicle_core.validation.stokeslet import HASIMOTO, hydrodynamic_radius


def hasimoto_D(kT, R_h, L):
    x = R_h / L
    return kT / (6 * np.pi * R_h) * (1 - HASIMOTO * x + 4 * np.pi / 3 * x**3 - 27.4 * x**6)


def setup(N, coupling):
    be = get_backend("numpy")
    g = Grid(N, float(N))
    W = sharpening_symbol(N, "peskin4", 0.01) if coupling == "sharp" else None
    st = StokesSolver(g, be, force_filter=W)
    return g, st, IBMMobility(Coupler(g, be), st)


def self_mobility(mob, rng, n=64):
    vals = []
    for _ in range(n):
        x = rng.uniform(0.0, 1.0, (1, 3))
        vals.append(np.trace(mobility_matrix(mob, x)) / 3)
    return float(np.mean(vals)), float(np.std(vals) / np.mean(vals))


def diffuse(N, coupling, steps, markers, seed, lag, kT=1.0, dt=1.0):
    g, st, mob = setup(N, coupling)
    noise = ThermalNoise(st, kT, seed=seed)
    n1 = round(markers ** (1 / 3))
    s = (np.arange(n1) + 0.5) * (g.L / n1) - g.L / 2
    X = np.stack(np.meshgrid(s, s, s, indexing="ij"), -1).reshape(-1, 3) + 0.37  # off the nodes
    traj = np.empty((steps + 1,) + X.shape)
    traj[0] = X
    t0 = time.perf_counter()
    for n in range(steps):
        mob.prepare(X)
        X = X + mob.coupler.interpolate(noise.displacement(dt, n))
        traj[n + 1] = X
    wall = time.perf_counter() - t0
    inc = np.diff(traj, axis=0)
    sq = (inc**2).sum(-1) / (6 * dt)  # (steps, markers)
    nb = 20
    blocks = sq[: steps // nb * nb].reshape(nb, -1).mean(1)
    D_inc, e_inc = blocks.mean(), blocks.std(ddof=1) / np.sqrt(nb)
    disp = traj[lag:] - traj[:-lag]
    msd = (disp**2).sum(-1) / (6 * lag * dt)  # overlapping windows (steps - lag + 1, markers)
    # block means over non-overlapping stretches of length >= lag
    nbm = max(4, (steps - lag) // (2 * lag))
    bl = msd[: (len(msd) // nbm) * nbm].reshape(nbm, -1).mean(1)
    return D_inc, e_inc, bl.mean(), bl.std(ddof=1) / np.sqrt(nbm), wall / steps


def drift(coupling, rng, N=16):
    g, st, mob = setup(N, coupling)
    m0, spread = self_mobility(mob, rng, 32)
    single = np.array([np.linalg.norm(mobility_divergence(mob, rng.uniform(0, 1, (1, 3)), 1e-4))
                       for _ in range(32)]) / (m0 / g.h)
    from vesicle_core.geometry.mesh import icosphere

    V, _ = icosphere(2)
    V = 4.0 * V / np.linalg.norm(V, axis=1, keepdims=True)
    # the same sphere at 4 random sub-grid shifts: per vertex, the shift mean is the systematic part of the drift
    # (what survives as the membrane moves over the grid), the rest averages out
    divs = np.array([mobility_divergence(mob, V + rng.uniform(0, 1, 3), 1e-4) for _ in range(4)]) / (m0 / g.h)
    d = np.linalg.norm(divs, axis=2).ravel()
    systematic = np.linalg.norm(divs.mean(0), axis=1)
    radial = np.einsum("vk,vk->v", divs.mean(0), V / 4.0)
    return m0, spread, single, d, systematic, radial


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--N", type=int, nargs="+", default=[16, 32])
    ap.add_argument("--steps", type=int, default=8000)
    ap.add_argument("--markers", type=int, default=8)
    ap.add_argument("--lag", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    print("| coupling | N | R_h/h (N=64) | D_H (Hasimoto) | kT <M_self> | D_inc | D_msd (lag) | D_inc/D_H - 1 "
          "| D_msd/D_H - 1 | ms/step |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for coupling in ("kernel", "sharp"):
        R_h = hydrodynamic_radius("peskin4", coupling, 0.01, N=64)
        for N in a.N:
            _, _, mob = setup(N, coupling)
            m_self, _ = self_mobility(mob, rng)
            DH = hasimoto_D(1.0, R_h, float(N))
            Di, ei, Dm, em, w = diffuse(N, coupling, a.steps, a.markers, a.seed, a.lag)
            print(f"| {coupling} | {N} | {R_h:.4f} | {DH:.5f} | {m_self:.5f} | {Di:.5f} +- {ei:.5f} | "
                  f"{Dm:.5f} +- {em:.5f} ({a.lag}) | {Di / DH - 1:+.4f} +- {ei / DH:.4f} | "
                  f"{Dm / DH - 1:+.4f} +- {em / DH:.4f} | {1e3 * w:.2f} |", flush=True)
    print()
    print("| coupling | M_self h | self spread (sub-grid) | single marker: mean / max "
          "| sphere vertices: mean / max | sphere, shift mean: mean / max | its radial part, mean |")
    print("|---|---|---|---|---|---|---|")
    for coupling in ("kernel", "sharp"):
        m0, spread, single, d, sy, rad = drift(coupling, rng)
        print(f"| {coupling} | {m0:.5f} | {spread:.2e} | {single.mean():.2e} / {single.max():.2e} | "
              f"{d.mean():.2e} / {d.max():.2e} | {sy.mean():.2e} / {sy.max():.2e} | {rad.mean():+.2e} |", flush=True)


if __name__ == "__main__":
    main()
