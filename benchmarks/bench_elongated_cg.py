"""CG iterations of the tension solve over the first steps of a run, and the mesh they act on.

Why does the elongated vesicle (Delta = 0.997) need far more CG iterations per step at 256^3 than at 128^3
(docs/history/solver.md)? This runs the first ``--steps`` steps of a case with the inextensible scheme and prints, per
step, the step length, the CG iterations and the warm-start residual, plus the quality of the starting mesh
(aspect ratio, shortest edge over h). Run by hand; quote timings with what else ran on the machine:

    python benchmarks/bench_elongated_cg.py --N 128 --n-vertices 2562 --delta 0.997 --S 237 --steps 12
    python benchmarks/bench_elongated_cg.py --N 256 --n-vertices 10242 --delta 0.997 --S 237 --steps 6
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from vesicle_core.geometry import mesh as M
from vesicle_core.model.run_config import legacy_config
from vesicle_core.model.units import chi_from_S
from vesicle_core.solver import tension as T
from vesicle_core.solver.simulate import _Run


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--N", type=int, default=128)
    ap.add_argument("--n-vertices", type=int, default=2562)
    ap.add_argument("--delta", type=float, default=0.997)
    ap.add_argument("--S", type=float, default=237.0)
    ap.add_argument("--steps", type=int, default=12)
    ap.add_argument("--dtype", default="float32")
    a = ap.parse_args()

    mesh = M.make_vesicle(family="quasiuniform", n_vertices=a.n_vertices, target_delta=a.delta)
    cfg = legacy_config(chi=chi_from_S(a.S, mesh.excess_area()), N=a.N, scheme="inextensible", dtype=a.dtype)
    q = M.mesh_quality(mesh.vertices, mesh.faces)
    X, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    e = X[f[:, [1, 2, 0]]] - X[f]  # (F, 3 edges, 3)
    shape = 4 * np.sqrt(3) * 0.5 * np.linalg.norm(np.cross(e[:, 0], -e[:, 2]), axis=1) / (e**2).sum(axis=(1, 2))
    print(f"Delta = {mesh.excess_area():.3f}, S = {a.S:g}, N = {a.N}, {mesh.n_vertices} vertices, h = {cfg.h:.4g}; "
          f"mesh: triangle quality 4 sqrt(3) A / sum l^2 median {np.median(shape):.3f} min {shape.min():.3f}, "
          f"aspect max {q['aspect_max']:.3f}, shortest edge {q['edge_min'] / cfg.h:.2f} h, mean edge "
          f"{q['edge_mean'] / cfg.h:.2f} h")

    record = []
    solve = T.TensionSolver._solve

    def recorded(self, geo, F, u_inf, area_error, dt, sigma0):
        t0 = time.perf_counter()
        out = solve(self, geo, F, u_inf, area_error, dt, sigma0)
        record.append((dt, self.last.iterations, self.last.residual0, float(np.abs(out[0]).max()),
                       time.perf_counter() - t0))
        return out

    T.TensionSolver._solve = recorded  # the benchmark only listens; the solve itself is unchanged
    with tempfile.TemporaryDirectory() as d:
        _Run(mesh, cfg, Path(d), False).loop(a.steps)
    print(f"{'step':>4} {'dt [tau]':>10} {'CG it':>6} {'warm res':>9} {'max|sigma|':>10} {'wall [s]':>8}")
    for i, (dt, it, r0, smax, w) in enumerate(record):
        print(f"{i:4d} {dt:10.3e} {it:6d} {r0:9.2e} {smax:10.4g} {w:8.1f}")


if __name__ == "__main__":
    main()
