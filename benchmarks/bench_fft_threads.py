"""FFT threads and precision for one steady Stokes solve (the unit of cost of every scheme).

    python benchmarks/bench_fft_threads.py [--sizes 128 256] [--repeats 7]

For each grid N and dtype, one StokesSolver.velocity (3-component rfftn, projection, irfftn) with fft_workers 1
and 2, timed round-robin in one process (medians), and the ratios workers-2 / workers-1 and float32 / float64.
Run it on an otherwise idle machine: a second process on the other core makes workers = 2 look worse than it is.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402

from vesicle_core.solver.backend import get_backend  # noqa: E402
from vesicle_core.solver.bench import interleaved_ms  # noqa: E402
from vesicle_core.solver.ibm import Grid  # noqa: E402
from vesicle_core.solver.stokes import StokesSolver  # noqa: E402


def main(sizes, repeats):
    for N in sizes:
        grid = Grid(N, 5.0)
        fns = {}
        for dtype in ("float64", "float32"):
            for w in (1, 2):
                be = get_backend("numpy", dtype, fft_workers=w)
                st = StokesSolver(grid, be)
                f = be.zeros(grid.field_shape)
                f[:, 1, 2, 3] = 1.0
                out = be.empty(grid.field_shape)
                st.velocity(f, out=out)  # plan (FFTW_MEASURE at 256^3) outside the timing
                fns[f"{dtype}/w{w}"] = (lambda st=st, f=f, out=out: st.velocity(f, out=out))
        ms = interleaved_ms(fns, repeats)[0]
        print(f"N = {N}: " + "  ".join(f"{k} {v:.1f} ms" for k, v in ms.items()))
        for dtype in ("float64", "float32"):
            print(f"   {dtype}: 2 workers / 1 worker = {ms[f'{dtype}/w2'] / ms[f'{dtype}/w1']:.2f}")
        print(f"   1 worker: float32 / float64 = {ms['float32/w1'] / ms['float64/w1']:.2f}", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args()
    main(a.sizes, a.repeats)
