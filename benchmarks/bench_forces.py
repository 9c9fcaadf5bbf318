"""Time membrane forces (bending + area penalty + volume penalty) on icosphere meshes.

Run by hand:  python benchmarks/bench_forces.py [--levels 5 6] [--repeats 15]
Reports the median wall time per force evaluation and the ratio to a bare vertex gather, so the
number travels between machines better than the absolute time.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from vesicle_core.geometry import mesh as M  # noqa: E402
from vesicle_core.solver import membrane as B  # noqa: E402


def median_time(fn, repeats):
    fn()
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[5, 6])
    ap.add_argument("--repeats", type=int, default=15)
    a = ap.parse_args()
    print(f"{'level':>5} {'vertices':>9} {'model':>12} {'forces ms':>10} {'gather ms':>10} {'ratio':>6}")
    for level in a.levels:
        m = M.make_vesicle("icosphere", level=level)
        X = m.vertices * 1.001
        for model in B.AREA_MODELS:
            mem = B.Membrane.from_mesh(m.vertices, m.faces, Lambda=1e6, K_volume=1e5, area_model=model)
            tf = median_time(lambda mem=mem, X=X: mem.forces(X), a.repeats)
            tg = median_time(lambda X=X, faces=m.faces: X[faces], a.repeats)
            print(f"{level:>5} {m.n_vertices:>9} {model:>12} {tf * 1e3:>10.2f} {tg * 1e3:>10.3f} {tf / tg:>6.0f}")


if __name__ == "__main__":
    main()
