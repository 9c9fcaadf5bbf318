"""Resolution of the IBM membrane: single-mode relaxation rates against linear theory, per grid and kernel.

For each kernel (3-point, 4-point, 6-point) and grid N (mesh edge ~ 2h), the relaxation rate of r = 1 + eps Y_l0
(vesicle_core.relaxation) over the clean-interface theory, corrected for the periodic box, and l_res: the highest
l whose ratio stays within 5% of 1. Also per kernel: the hydrodynamic radius (self-mobility of a marker) and the
translation-invariance error (spread of the self-mobility over random sub-grid positions).

Box correction: the rate of l = 2 depends on the box as r(L) = r_inf - c / L^3 (measured at L = 5, 7, 9, 12 R,
same h: 0.912, 0.942, 0.951, 0.956 for the 4-point kernel at h = 0.078); modes l >= 3 move by < 0.1%. The
correction factor is r(5) / r_inf from L = 5 and 7 R.

    python benchmarks/bench_resolution.py [--Ns 64 128 256] [--kernels roma3 peskin4 bao6] [--inextensible]

Cost on 2 cores: N = 64 a few seconds, 128 ~ 1 min, 256 ~ 10 min per kernel (meshes of 10242 vertices).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from vesicle_core.relaxation import default_vertices, l_res, mode_rate

LS = (2, 3, 4, 6, 8, 10, 13, 16, 20, 25, 30, 40)
VERTICES = {32: 642, 64: 642, 128: 2562, 256: 10242}  # the project's meshes, edge ~ 2h at L = 5 R


def box_factor(N, nv, kernel):
    """r(L = 5) / r(L = inf) for l = 2, from L = 5 and 7 R at the same h (r = r_inf - c / L^3)."""
    h = 5.0 / N
    N7 = 2 * round(7.0 / h / 2)
    r5 = mode_rate(2, N, nv, L=5.0, kernel=kernel).ratio
    r7 = mode_rate(2, N7, nv, L=N7 * h, kernel=kernel).ratio
    L5, L7 = 5.0, N7 * h
    c = (r7 - r5) / (1 / L5**3 - 1 / L7**3)
    r_inf = r7 + c / L7**3
    return r5 / r_inf


def kernel_properties(kernel, N=64, n=40, seed=0):
    """Hydrodynamic radius a_h / h and relative spread of the self-mobility over sub-grid positions."""
    from vesicle_core.backend import get_backend
    from vesicle_core.ibm import Coupler, Grid
    from vesicle_core.mobility import IBMMobility
    from vesicle_core.stokes import StokesSolver

    grid, be = Grid(N, 5.0), get_backend("numpy")
    mob = IBMMobility(Coupler(grid, be, kernel=kernel), StokesSolver(grid, be))
    rng = np.random.default_rng(seed)
    m = []
    for _ in range(n):
        X = rng.uniform(0, grid.h, (1, 3))
        mob.prepare(X)
        F = np.array([[1.0, 0.0, 0.0]])
        m.append(mob.apply(F)[0, 0])
    m = np.array(m)
    h = grid.h
    return {"a_h_over_h": float(1.0 / (6 * math.pi * m.mean() * h)), "self_mobility_spread": float(m.std() / m.mean())}


def main(Ns, kernels, membrane="clean", tol=0.05):
    out = {}
    for kernel in kernels:
        props = kernel_properties(kernel)
        print(f"{kernel}: a_h = {props['a_h_over_h']:.3f} h, self-mobility spread {props['self_mobility_spread']:.2e}",
              flush=True)
        out[kernel] = {"properties": props, "grids": {}}
        for N in Ns:
            t0 = time.perf_counter()
            nv = VERTICES.get(N) or default_vertices(N)
            bf = box_factor(N, nv, kernel)
            ratios = {}
            for l in LS:
                if l * 5.0 / N > 2.0:
                    break
                r = mode_rate(l, N, nv, kernel=kernel, membrane=membrane).ratio
                ratios[l] = r / bf if l == 2 else r
            lr = l_res(ratios, tol)
            out[kernel]["grids"][N] = {"n_vertices": nv, "box_factor_l2": bf, "ratios": ratios, "l_res": lr}
            print(f"  N = {N:4d} ({nv} vertices): l_res = {lr:3d}  box factor (l=2) {bf:.4f}  ratios "
                  + " ".join(f"{l}:{r:.3f}" for l, r in ratios.items()) + f"  ({time.perf_counter() - t0:.0f} s)",
                  flush=True)
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--Ns", type=int, nargs="+", default=[64, 128, 256])
    ap.add_argument("--kernels", nargs="+", default=["roma3", "peskin4", "bao6"])
    ap.add_argument("--inextensible", action="store_true", help="vesicle rates Gamma_l (tension solve) instead")
    ap.add_argument("--json", help="write the table here")
    a = ap.parse_args()
    res = main(a.Ns, a.kernels, "inextensible" if a.inextensible else "clean")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(res, fh, indent=1)
