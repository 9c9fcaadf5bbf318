"""The IBM's mean membrane tension in the stationary stretched state against the PA's (S - Gamma_2) / A_2.

Run by hand (mesh + stretch-only runs + table, from scratch; finished runs under --out are reused):
    python studies/stationary_tension.py [--deltas 0.03 0.06 0.116] [--L 5 7.03125] [--h 0.078125]
        [--S 553] [--n-vertices 642] [--stretch 1.0] [--set KEY=VALUE ...] [--out DIR] [--json FILE]

Every point runs the forward (stretching) flow only, for --stretch strain units, then 0.02 after the reversal
(t_end; nothing after the reversal enters the table). The grid spacing h is the same in every box: N = L / h must
come out an even integer (the solver's N is even; pyFFTW and scipy.fft take any size, 2-3-5-smooth ones are the
fast ones: L = 5, 7.03125, 9.375 R give N = 64, 90, 120 at h = 5/64).

Columns, per (Delta, L):
* sigma_IBM: validation.box_tension, the trajectory's mean tension at the reversal (time 0) [kappa/R^2];
* drift: (sigma(0) - sigma(-0.2)) / sigma(0), how far from stationary the tension still is;
* Delta_rev: the excess area A / R_V^2 - 4 pi of the membrane at the reversal (the inextensible scheme's
  compliance sigma / Lambda adds 4 pi sigma / Lambda to the mesh's Delta);
* sigma_PA: validation.study.pa_stretch_tension(S), S from the run's chi and the mesh's Delta (it does not depend
  on Delta at fixed S); sigma_PA,rev the same with S from chi and Delta_rev;
* Delta_ell0, Delta_ell: the excess area of the smooth ellipsoid fitted to the vertices (analysis.shape.fit_ellipsoid)
  in the first frame and at the reversal: the Delta the l = 2 shape carries, without the polyhedron's own excess
  (a 642-vertex sphere has Delta = 0.014, a 2562-vertex one 0.0034); sigma_PA,ell: S from chi and Delta_ell;
* off, off_rev, off_ell: sigma_IBM over sigma_PA, sigma_PA,rev and sigma_PA,ell, less 1.
Per Delta with two or more boxes: sigma_inf from each pair of neighbouring boxes by validation.image_extrapolation
(sigma(L) = sigma_inf + c / L^3, periodic images), against the larger box's PA values; with three boxes the two
pairs' agreement tests that law.
The study in docs/history/solver.md ("The stationary tension against the PA") ran
    python studies/stationary_tension.py --deltas 0.03 0.06 0.116 0.2 --L 5 7.03125 9.375
    python studies/stationary_tension.py --deltas 0.03 0.06 0.116 0.2 --L 5 --set Lambda=1e8 --set cg_maxiter=1000
    python studies/stationary_tension.py --deltas 0.116 0.03 0.2 --L 5 --h 0.0390625 --n-vertices 2562
(13, 70, 125 s per run at N = 64, 90, 120 with 642 vertices; ~55 s at Lambda = 1e8; 156-179 s at N = 128 with
2562 vertices; one run at a time beside another job on a 2-core machine).
Quote timings with what else ran on the machine.

Feeds docs/history/solver.md, "The stationary tension against the PA: periodic images, excess area, grid".
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np
import xarray as xr

from vesicle_core.analysis.shape import fit_ellipsoid
from vesicle_core.cli.args import parse_set
from vesicle_core.geometry import mesh as M
from vesicle_core.geometry.surface import enclosed_volume, surface_area
from vesicle_core.model.run_config import legacy_config
from vesicle_core.model.units import S_from_chi, chi_from_S
from vesicle_core.solver.simulate import run
from vesicle_core.validation.box import box_tension, image_extrapolation
from vesicle_core.validation.study import pa_stretch_tension


def grid_size(L, h):
    """N = L / h, which must be an even integer (the same h in every box)."""
    n = L / h
    N = int(round(n))
    if abs(n - N) > 1e-9 * n or N % 2:
        raise SystemExit(f"L = {L} at h = {h} gives N = {n:g}: choose L = (even integer) x h")
    return N


def reversal_delta(traj):
    """Excess area A / R_V^2 - 4 pi of the frame at the reversal (time 0), R_V from the frame's volume."""
    i = int(np.argmin(np.abs(traj["time"].values)))
    X = np.stack([traj[c].values[i] for c in ("node_x", "node_y", "node_z")], axis=1)
    f = traj["face_node_connectivity"].values
    R = (3.0 * enclosed_volume(X, f) / (4.0 * math.pi)) ** (1.0 / 3.0)
    return surface_area(X, f) / R**2 - 4.0 * math.pi


def ellipsoid_delta(traj, time=0.0):
    """Excess area of the smooth ellipsoid fitted to the vertices of the frame at ``time``: the Delta that the
    l = 2 shape carries, without the polyhedron's own excess (a 642-vertex sphere has Delta = 0.014).
    Area 4 pi abc R_G(a^-2, b^-2, c^-2) (Carlson), volume 4/3 pi abc."""
    from scipy.special import elliprg

    i = int(np.argmin(np.abs(traj["time"].values - time)))
    X = np.stack([traj[c].values[i] for c in ("node_x", "node_y", "node_z")], axis=1)
    a, b, c = fit_ellipsoid(X)[1]
    return 4.0 * math.pi * (a * b * c * elliprg(a**-2, b**-2, c**-2) / (a * b * c) ** (2.0 / 3.0) - 1.0)


def drift(traj, window=0.2):
    t, s = traj["time"].values, traj["tension"].values
    i0, i1 = int(np.argmin(np.abs(t))), int(np.argmin(np.abs(t + window)))
    return float((s[i0] - s[i1]) / s[i0])


def one_point(delta, L, N, a, extra):
    out = Path(a.out)
    mesh_path = out / f"mesh_v{a.n_vertices}_d{delta:g}.nc"
    if not mesh_path.exists():
        M.save(M.make_vesicle("quasiuniform", n_vertices=a.n_vertices, target_delta=delta), mesh_path)
    mesh = M.load(mesh_path)
    chi = chi_from_S(a.S, mesh.excess_area())
    tag = "_".join(f"{k}{v}" for k, v in sorted(extra.items()))
    rundir = out / f"S{a.S:g}_v{a.n_vertices}_d{delta:g}_L{L:g}_N{N}{'_' + tag if tag else ''}"
    traj_path = rundir / "trajectory.nc"
    wall = math.nan
    if not traj_path.exists():
        params = dict(N=N, L=L, chi=chi, scheme="inextensible", stretch=a.stretch, t_end=0.02, output_every=0.02,
                      fft_workers=1)
        params.update(extra)
        t0 = time.perf_counter()
        run(mesh, legacy_config(**params), rundir, progress=False)  # the defaults it was run with
        wall = time.perf_counter() - t0
    with xr.open_dataset(traj_path) as traj:
        traj = traj.load()
    d_rev = reversal_delta(traj)
    sigma = box_tension(traj)
    pa = pa_stretch_tension(S_from_chi(chi, mesh.excess_area()))
    pa_rev = pa_stretch_tension(S_from_chi(chi, d_rev))
    d_ell, d_ell0 = ellipsoid_delta(traj), ellipsoid_delta(traj, float(traj["time"].values[0]))
    pa_ell = pa_stretch_tension(S_from_chi(chi, d_ell))
    return {"delta": delta, "delta_mesh": mesh.excess_area(), "delta_rev": d_rev, "L": L, "N": N, "h": L / N,
            "chi": chi, "sigma": sigma, "drift": drift(traj), "sigma_pa": pa, "off": sigma / pa - 1,
            "sigma_pa_rev": pa_rev, "off_rev": sigma / pa_rev - 1,
            "delta_ell0": d_ell0, "delta_ell": d_ell, "sigma_pa_ell": pa_ell, "off_ell": sigma / pa_ell - 1,
            "steps": int(traj.attrs.get("steps", -1)),
            "wall_s": float(traj.attrs.get("wall_time_s", wall)), "set": extra}


def table(rows):
    print("| Delta | Delta_rev | Delta_ell0 | Delta_ell | L [R] | N | h [R] | chi | sigma_IBM | drift | sigma_PA | "
          "off | sigma_PA,rev | off_rev | sigma_PA,ell | off_ell | wall [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['delta']:g} | {r['delta_rev']:.4f} | {r['delta_ell0']:.4f} | {r['delta_ell']:.4f} | "
              f"{r['L']:g} | {r['N']} | {r['h']:.4g} | {r['chi']:.2f} | "
              f"{r['sigma']:.1f} | {r['drift']:+.1e} | {r['sigma_pa']:.1f} | {100 * r['off']:+.1f}% | "
              f"{r['sigma_pa_rev']:.1f} | {100 * r['off_rev']:+.1f}% | {r['sigma_pa_ell']:.1f} | "
              f"{100 * r['off_ell']:+.1f}% | {r['wall_s']:.0f} |")
    print()
    print("| Delta | boxes | sigma_inf | off (sigma_PA) | off (sigma_PA,rev) | off (sigma_PA,ell) |")
    print("|---|---|---|---|---|---|")
    ext = []
    for d in sorted({r["delta"] for r in rows}):
        rs = sorted((r for r in rows if r["delta"] == d), key=lambda r: r["L"])
        for small, large in zip(rs, rs[1:], strict=False):
            s_inf = image_extrapolation(small["L"], small["sigma"], large["L"], large["sigma"])
            ext.append({"delta": d, "L_small": small["L"], "L_large": large["L"], "sigma_inf": s_inf,
                        "off": s_inf / large["sigma_pa"] - 1, "off_rev": s_inf / large["sigma_pa_rev"] - 1,
                        "off_ell": s_inf / large["sigma_pa_ell"] - 1})
            print(f"| {d:g} | {small['L']:g}, {large['L']:g} | {s_inf:.1f} | {100 * ext[-1]['off']:+.1f}% | "
                  f"{100 * ext[-1]['off_rev']:+.1f}% | {100 * ext[-1]['off_ell']:+.1f}% |")
    return ext


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--deltas", type=float, nargs="+", default=[0.03, 0.06, 0.116])
    p.add_argument("--L", type=float, nargs="+", default=[5.0, 7.03125], help="box edges [R]")
    p.add_argument("--h", type=float, default=5.0 / 64, help="grid spacing [R], the same in every box")
    p.add_argument("--S", type=float, default=553.0, help="flow strength S (chi = chi_from_S(S, mesh Delta))")
    p.add_argument("--n-vertices", type=int, default=642)
    p.add_argument("--stretch", type=float, default=1.0, help="forward-flow phase [gamma_dot t]")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="further run parameter for every point (repeatable), e.g. Lambda=1e8")
    p.add_argument("--out", default="stationary_runs")
    p.add_argument("--json", help="also write the rows and extrapolations here")
    a = p.parse_args(argv)
    extra = parse_set(a.set)
    Ns = [grid_size(L, a.h) for L in a.L]
    rows = []
    for d in a.deltas:
        for L, N in zip(a.L, Ns, strict=True):
            rows.append(one_point(d, L, N, a, extra))
            r = rows[-1]
            print(f"# Delta {d:g} L {L:g} N {N}: sigma {r['sigma']:.1f} (PA {r['sigma_pa']:.1f}, "
                  f"{100 * r['off']:+.1f}%), wall {r['wall_s']:.0f} s", flush=True)
    ext = table(rows)
    if a.json:
        Path(a.json).write_text(json.dumps({"rows": rows, "extrapolated": ext, "S": a.S,
                                            "n_vertices": a.n_vertices}, indent=1))


if __name__ == "__main__":
    main()
