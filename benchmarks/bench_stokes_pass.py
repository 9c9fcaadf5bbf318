"""The steady Stokes projection as one compiled pass (numba) against the NumPy passes, alone and in a solve.

Run by hand (needs numba); quote the result with what else ran on the machine:

    python benchmarks/bench_stokes_pass.py [--sizes 128 256] [--reps 15] [--dtype float32]

For each N: the projection alone on one 3-component spectrum, and a whole steady solve (rfftn, projection,
irfftn; pyFFTW when installed) with either pass. The two are timed alternately, so a load that changes
during the run hits both; reported are the medians and the median of the per-pair ratios, and whether the
two velocities are identical bit for bit (they should be: same operations in the same order).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time

import numpy as np

from vesicle_core.solver.backend import get_backend
from vesicle_core.solver.ibm import Grid
from vesicle_core.solver.stokes import StokesSolver


def _pair_times(fa, fb, reps):
    ta, tb = [], []
    for _ in range(reps):
        for f, t in ((fa, ta), (fb, tb)):
            t0 = time.perf_counter()
            f()
            t.append(time.perf_counter() - t0)
    ta, tb = np.array(ta), np.array(tb)
    return np.median(ta), np.median(tb), np.median(tb / ta)


def bench_size(N, be, dtype, reps):
    g = Grid(N, 5.0)
    plain, fused = StokesSolver(g, be, fused=False), StokesSolver(g, be, fused=True)
    f = np.random.default_rng(0).standard_normal((3, N, N, N)).astype(dtype)
    out = np.empty_like(f)
    same = np.array_equal(plain.velocity(f), fused.velocity(f))  # also plans the FFTs and compiles the pass
    spec = plain._forward(f).copy()
    work = [spec.copy(), spec.copy()]
    sym = [s._steady_symbols(1.0) for s in (plain, fused)]

    def pass_of(k, s):
        def run():
            work[k][...] = spec
            s._apply_steady(s._view(work[k]), *sym[k])

        return run

    p_np, p_nb, p_r = _pair_times(pass_of(0, plain), pass_of(1, fused), reps)
    s_np, s_nb, s_r = _pair_times(lambda: plain.velocity(f, out=out), lambda: fused.velocity(f, out=out), reps)
    print(f"N = {N}: projection {p_np * 1e3:.1f} -> {p_nb * 1e3:.1f} ms (ratio {p_r:.2f}); steady solve "
          f"{s_np * 1e3:.0f} -> {s_nb * 1e3:.0f} ms (ratio {s_r:.2f}); identical velocities: {same}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--dtype", default="float32")
    a = ap.parse_args()
    be = get_backend("numpy", dtype=a.dtype)
    print(f"backend {be.fft_library}, {a.dtype}, 1 thread; {a.reps} alternating repetitions")
    for N in a.sizes:
        bench_size(N, be, a.dtype, a.reps)


if __name__ == "__main__":
    main()
