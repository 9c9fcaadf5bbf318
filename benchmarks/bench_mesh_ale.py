"""What the mesh ALEs cost per call and what they do, on the frames of a finished run (run by hand).

    python benchmarks/bench_mesh_ale.py TRAJ.nc [--frames 10] [--h H] [--damp 1e-3]

For `mesh_ale` area, shape and quality (mesh_ale.AreaALE, ShapeALE, QualityALE) on consecutive stored frames
k -> k + 1: the membrane's displacement dX = X_{k+1} - X_k (several steps: an upper bound on one step's), the area
error of frame k against the reference (first) frame, and per ALE the median seconds per call (its damped least
squares solved by a sparse factorisation, mesh_ale.damped_least_squares), the largest |w| / h, and the mesh
quality (min, median) and triangle strain (against A0) of X_k + dX + w against X_k + dX. Report ratios of the ALEs
measured in one run: timings here are noisy.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time

import numpy as np
import xarray as xr

from vesicle_core.solver import membrane as Mb
from vesicle_core.solver.mesh_ale import AreaALE, QualityALE, ShapeALE
from vesicle_core.solver.tension_harmonic import HarmonicSpace


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trajectory")
    ap.add_argument("--frames", type=int, default=10, help="frame pairs to use, from the reversal on")
    ap.add_argument("--h", type=float, default=None, help="grid spacing (default: the run's L / N)")
    ap.add_argument("--damp", type=float, default=1e-3, help="the least squares' Tikhonov weight (AreaALE.damp)")
    a = ap.parse_args(argv)
    ds = xr.open_dataset(a.trajectory)
    faces = ds.face_node_connectivity.values.astype(np.int64)
    X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1).astype(float)
    h = a.h or float(ds.attrs["L"]) / float(ds.attrs["N"])
    topo = Mb.Topology(faces, X.shape[1])
    A0 = Mb.geometry(X[0], topo).area
    l_max = int(ds.attrs.get("tension_l_used", 0)) or None
    space = HarmonicSpace(X[0], faces, A0, l_max)
    rev = int(np.argmax(ds.flow_sign.values < 0))
    ks = range(rev, min(rev + a.frames, X.shape[0] - 1))
    ales = {"area": AreaALE(space, h, damp=a.damp),
            "shape": ShapeALE(space, h, X[0], faces, damp=a.damp),
            "quality": QualityALE(space, h, X[0], faces, damp=a.damp)}
    print(f"{a.trajectory}: {X.shape[1]} vertices, l_t = {space.l_max}, h = {h:.4g}, frames {ks.start}..{ks.stop}")
    out = {}
    for name, ale in ales.items():
        ale.max_step, ale.follow = 1e9, 0.0  # uncapped: what the least squares asks for
        secs, wmax, qmin, qmed, strain = [], [], [], [], []
        for k in ks:
            geo = Mb.geometry(X[k], topo)
            dX = X[k + 1] - X[k]
            t0 = time.perf_counter()
            w = np.asarray(ale(X[k], geo, topo, dX, geo.area - A0))
            secs.append(time.perf_counter() - t0)
            g1 = Mb.geometry(X[k] + dX + w, topo)
            q = Mb.triangle_quality(g1)
            wmax.append(np.linalg.norm(w, axis=1).max() / h)
            qmin.append(q.min())
            qmed.append(np.median(q))
            strain.append(np.abs(g1.area / A0 - 1).max())
        out[name] = np.median(secs)
        print(f"  {name:7s}: {np.median(secs) * 1e3:7.1f} ms/call, "
              f"max |w|/h {np.max(wmax):.3g}, quality min {np.min(qmin):.3f} median {np.median(qmed):.3f}, "
              f"triangle strain max {np.max(strain):.3g}")
    r = {k: out[k] / out["area"] for k in ("shape", "quality")}
    print(f"  time per call over area's: shape {r['shape']:.2f}, quality {r['quality']:.2f}")


if __name__ == "__main__":
    main()
