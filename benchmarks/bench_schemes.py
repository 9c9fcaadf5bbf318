"""The time-stepping schemes on the same case: steps, Stokes solves, wall time, inextensibility, physics.

Run by hand:
    python benchmarks/bench_schemes.py [--N 64] [--n-vertices 642] [--chi 267.8] [--schemes explicit inextensible]
        [--lambda-explicit 1e7] [--stretch 1] [--t-end 1] [--dtype float64] [--out DIR]

A scheme may carry the inextensible scheme's CG preconditioner after a slash, and any run parameters after plus
signs: `inextensible/local+cg_tol=1e-6`.

* explicit: the paper's method, the stiff area penalty alone (Lambda = 1.5e4 chi by default; --lambda-explicit
  sets it, e.g. 1e7 for a strain <= 0.1% at chi = 268);
* projection: a global tension multiplier holds the total area, 10x softer local penalty;
* inextensible: a tension per triangle solved every step (PCG), adaptive step.

Reported per scheme: steps, Stokes solves, CG iterations (median / mean / max), wall time, the rms and max area
strain of triangles and of vertex dual cells over every frame (against the initial mesh), the checkerboard
measure (rms difference of the vertex-averaged tension between neighbouring vertices over its rms, worst frame in
0 <= gamma_dot t <= 0.5), and the physics: l_* (eq. 31), l_peak, t_*. The first scheme is the reference of the
last lines: l_* difference and the rms difference of Delta_2(t) over 0 <= gamma_dot t <= 1, relative to its rms.
Quote timings with what else ran on the machine.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import tempfile
import time

import numpy as np
import xarray as xr
import yaml

from vesicle_core.analysis.spectra import spectra_from_trajectory
from vesicle_core.geometry import mesh as M
from vesicle_core.model.parameters import SCHEMES
from vesicle_core.model.run_config import legacy_config
from vesicle_core.solver.simulate import run


def inextensibility(ds):
    """Triangle and dual-cell strain per frame and the checkerboard measure of the tension."""
    from vesicle_core.solver import membrane as B
    from vesicle_core.solver.tension import dual_areas, vertex_mean

    X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
    topo = B.Topology(ds.face_node_connectivity.values, X.shape[1])
    g0 = B.geometry(X[0], topo)
    a0, v0 = g0.area, dual_areas(g0, topo)
    f = topo.faces
    E = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0)
    rows = []
    for k in range(X.shape[0]):
        g = B.geometry(X[k], topo)
        sf, sv = g.area / a0 - 1, dual_areas(g, topo) / v0 - 1
        tv = vertex_mean(ds.face_tension.values[k].astype(float), g, topo)
        rms = np.sqrt(np.mean(tv**2))
        cb = np.sqrt(np.mean((tv[E[:, 0]] - tv[E[:, 1]]) ** 2)) / rms if rms > 0 else 0.0
        rows.append((np.sqrt(np.mean(sf**2)), np.abs(sf).max(), np.sqrt(np.mean(sv**2)), np.abs(sv).max(), cb))
    r = np.array(rows)
    t = ds.time.values
    w = (t >= 0) & (t <= 0.5)
    return {"face_strain_rms": r[:, 0].max(), "face_strain_max": r[:, 1].max(), "vertex_strain_rms": r[:, 2].max(),
            "vertex_strain_max": r[:, 3].max(), "checkerboard_worst": r[w, 4].max(),
            "checkerboard_median": float(np.median(r[w, 4]))}


def run_overrides(items):
    """{name: value} of KEY=VALUE strings, values read as YAML (numbers, null, booleans)."""
    out = {}
    for kv in items:
        k, _, v = kv.partition("=")
        v = yaml.safe_load(v)
        try:  # PyYAML reads 1e-6 (no dot) as a string
            v = float(v) if isinstance(v, str) else v
        except ValueError:
            pass
        out[k] = v
    return out


def one(label, mesh, a, outdir):
    head, *sets = label.split("+")
    scheme, _, precond = head.partition("/")
    kw = {"Lambda": a.lambda_explicit} if scheme == "explicit" and a.lambda_explicit else {}
    if precond:
        kw["cg_precond"] = precond
    kw.update(run_overrides(sets))  # run parameters after a plus: inextensible+cg_tol=1e-6
    cfg = legacy_config(chi=a.chi, N=a.N, stretch=a.stretch, t_end=a.t_end, output_every=0.02, scheme=scheme,
                    fft_workers=a.fft_workers, dtype=a.dtype, **kw)
    t = time.perf_counter()
    path = run(mesh, cfg, outdir, progress=False)
    wall = time.perf_counter() - t
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    spec = spectra_from_trajectory(ds)
    row = {
        "scheme": label, "steps": int(ds.attrs["steps"]), "stokes_solves": ds.attrs.get("stokes_solves", np.nan),
        "cg_median": ds.attrs.get("cg_iterations_median", np.nan),
        "cg_mean": ds.attrs.get("cg_iterations_mean", np.nan),
        "cg_max": ds.attrs.get("cg_iterations_max", np.nan), "wall_s": wall,
        "Lambda": ds.attrs["Lambda_eff"],
        "precond_s": ds.attrs.get("cg_precond_s", np.nan),  # local preconditioner: build, factorise, apply
        "max_volume_drift": float(np.abs(ds.volume_drift).max()), **inextensibility(ds),
        "l_star": float(spec.l_star), "l_peak": float(spec.l_peak), "t_star": float(spec.t_star),
    }
    return row, spec


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--N", type=int, default=64)
    ap.add_argument("--n-vertices", type=int, default=642)
    ap.add_argument("--chi", type=float, default=267.8)
    ap.add_argument("--delta", type=float, default=None,
                    help="excess area of the mesh (default: the 1:0.8:1 ellipsoid, Delta = 0.116)")
    ap.add_argument("--stretch", type=float, default=1.0)
    ap.add_argument("--t-end", type=float, default=1.0)
    ap.add_argument("--schemes", nargs="+", default=list(SCHEMES))
    ap.add_argument("--lambda-explicit", type=float, default=None)
    ap.add_argument("--fft-workers", type=int, default=1)
    ap.add_argument("--dtype", default="float64", choices=("float64", "float32"), help="grid fields and FFTs")
    ap.add_argument("--out", default=None, help="keep the runs here (default: a temporary directory)")
    a = ap.parse_args()
    if a.delta is None:
        mesh = M.make_vesicle("quasiuniform", n_vertices=a.n_vertices, axes=(1.0, 0.8, 1.0))
    else:  # the workflow's construction of a case of given excess area
        mesh = M.make_vesicle("quasiuniform", n_vertices=a.n_vertices, target_delta=a.delta)
    rows, specs = [], []
    with tempfile.TemporaryDirectory() as d:
        base = a.out or d
        for scheme in a.schemes:
            r, s = one(scheme, mesh, a, os.path.join(base, scheme.replace("/", "_")))
            rows.append(r)
            specs.append(s)
            print(f"{scheme}: done in {r['wall_s']:.0f} s", flush=True)
    print(f"N = {a.N}, {mesh.n_vertices} vertices, chi = {a.chi}, stretch {a.stretch} + {a.t_end} gamma_dot t")
    for k in rows[0]:
        vals = [r[k] for r in rows]
        print(f"{k:>20}: " + "  ".join(f"{v:>12.4g}" if not isinstance(v, str) else f"{v:>12}" for v in vals))
    ref = specs[0].Delta_l.sel(l=2).sel(time=slice(0.0, 1.0))
    for r, s in zip(rows[1:], specs[1:], strict=True):
        d2 = s.Delta_l.sel(l=2).interp(time=ref.time)
        rel = float(np.sqrt(np.mean((d2 - ref) ** 2)) / np.sqrt(np.mean(ref**2)))
        print(f"{r['scheme']} vs {rows[0]['scheme']}: l_* {r['l_star'] / rows[0]['l_star'] - 1:+.1%}, "
              f"Delta_2(t) rms difference {rel:.1%}, steps {rows[0]['steps'] / r['steps']:.1f}x fewer, "
              f"wall {rows[0]['wall_s'] / r['wall_s']:.1f}x less")


if __name__ == "__main__":
    main()
