"""Where the inextensible tension's variation sits in l: wrinkle scale or mesh scale (issue 10's checkerboard).

Run by hand on a finished trajectory:
    python studies/tension_spectrum.py TRAJECTORY.nc [--t-min 0] [--t-max 0.5] [--l-max 0]

The checkerboard measure (rms difference of the vertex-averaged tension between neighbouring vertices over its
rms) cannot tell a mesh-scale checkerboard from a smooth tension that varies on the wrinkles' own scale: a wave
of wavelength 4-5 edges already scores ~1. This script separates the two. Per frame it projects the per-triangle
tension on Y_lm (centroid rule, solid-angle weights, l <= L, default L = the mesh's resolvable l, pi R / mean
edge) and reports
- the shape's l_peak (the most excited l >= 3 of the frame's Delta_l);
- the share of the tension's variance at l = 2 (the flow's imprint), at 3 <= l <= L/2 (the wrinkles' band), at
  L/2 < l <= L, and above L (what the projection cannot hold: the mesh scale);
- the checkerboard measure of the raw tension and of its l <= L/2 part (harmonics.resolved_field, at the
  vertices), both over the rms of the raw vertex-averaged tension.
A tension that varies with the wrinkles has its variance near l_peak; a checkerboard has it above L.

Feeds docs/history/solver.md, "What the checkerboard is, and why the two criteria conflict on this discretisation".
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse

import numpy as np
import xarray as xr

from vesicle_core.analysis import harmonics as H
from vesicle_core.geometry import surface as Sf
from vesicle_core.geometry import ylm as Yl
from vesicle_core.geometry.mesh import unique_edges as edges  # noqa: E402
from vesicle_core.solver import membrane as B
from vesicle_core.solver.tension import vertex_mean


def analyse(path, t_min, t_max, l_max):
    ds = xr.open_dataset(path).load()
    faces = ds.face_node_connectivity.values
    X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
    topo = B.Topology(faces, X.shape[1])
    E = edges(faces)
    t = ds.time.values
    lres = Sf.resolvable_l_max(X[0], faces)
    L = l_max or lres
    half = L // 2
    print(f"{path}: {X.shape[1]} vertices, {faces.shape[0]} triangles, resolvable l {lres}, projecting to l {L}")
    print(f"{'gdt':>6} {'mean':>8} {'std':>7} {'l_peak':>6} {'l=2':>5} {'3..' + str(half):>6} "
          f"{str(half + 1) + '..' + str(L):>7} {'>' + str(L):>5} {'cb_raw':>6} {'cb_low':>6}")
    rows = []
    for k in np.flatnonzero((t >= t_min) & (t <= t_max)):
        v = X[k]
        s = ds.face_tension.values[k].astype(float)
        q = H.quadrature(v, faces, rule="centroid")
        c = Yl.project(s, q.theta, q.phi, q.weights, L)
        pw = (np.abs(c) ** 2).sum(axis=1) / (4 * np.pi)  # variance per l (R = 1: the sphere's area is 4 pi)
        dl = H.delta_l(H.decompose(v, faces, min(L, lres)))
        l_peak = int(np.argmax(dl[3:]) + 3)
        w = q.weights / q.weights.sum()
        var = np.sum(w * s**2) - np.sum(w * s) ** 2
        if not var > 0:
            continue
        shares = (pw[2] / var, pw[3:half + 1].sum() / var, pw[half + 1:].sum() / var, max(0.0, 1 - pw[1:].sum() / var))
        g = B.geometry(v, topo)
        tv = vertex_mean(s, g, topo)
        rms = np.sqrt(np.mean(tv**2))
        low = H.resolved_field(v, faces, s, half)
        nb = lambda x: np.sqrt(np.mean((x[E[:, 0]] - x[E[:, 1]]) ** 2))  # noqa: E731
        rows.append((t[k], s.mean(), np.sqrt(var), l_peak, *shares, nb(tv) / rms, nb(low) / rms))
        print(f"{t[k]:6.2f} {s.mean():8.1f} {np.sqrt(var):7.1f} {l_peak:6d} " + " ".join(f"{x:5.2f}" for x in shares)
              + f" {nb(tv) / rms:6.2f} {nb(low) / rms:6.2f}", flush=True)
    return np.array(rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trajectory")
    ap.add_argument("--t-min", type=float, default=0.0)
    ap.add_argument("--t-max", type=float, default=0.5)
    ap.add_argument("--l-max", type=int, default=0, help="projection degree (0: the mesh's resolvable l)")
    a = ap.parse_args()
    analyse(a.trajectory, a.t_min, a.t_max, a.l_max)


if __name__ == "__main__":
    main()
