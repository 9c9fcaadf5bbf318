"""The tension spaces of the inextensible scheme (issue 21) on finished runs: strains, mesh quality, checkerboard.

Run by hand on trajectories written by bench_schemes.py --out (or `vesicle run`):
    python benchmarks/bench_tension_space.py TRAJ.nc [TRAJ.nc ...] [--l-max L] [--ref TRAJ.nc]
    python benchmarks/bench_tension_space.py --inf-sup [--n-vertices 162 642 2562] [--l-max-list 5 10 20]

Per trajectory, over every frame (the worst frame is quoted):
- constrained strain: the W-orthogonal projection of the triangle strain (A - A0) / A0 on the harmonic space up to
  L (what tension_space harmonic holds; L = the trajectory's tension_l_max, or --l-max), area-weighted rms and max;
- triangle strain rms / max (the triangle space's constraint; a diagnostic for the harmonic space);
- mesh quality 4 sqrt(3) A / sum l^2 per triangle (1 equilateral), min and median;
- the raw tension's checkerboard measure (rms difference of the vertex-averaged tension between neighbouring
  vertices over its rms) in every frame after the reversal (gamma_dot t >= 0), and the share of its variance beyond
  the mesh's resolvable l (Y_lm projection, centroid rule, as studies/tension_spectrum.py);
- with --ref: l_*, t_* and the rms difference of Delta_2(t) over 0 <= gamma_dot t <= 1 against the reference run.

--inf-sup: the discrete inf-sup constant min |D^T B c| / |B c| (tension_harmonic.inf_sup; continuum 2 / R) of the
triangle space and of the harmonic space up to each L, on quasi-uniform S = 2224 reference meshes.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import math

import numpy as np
import xarray as xr

from vesicle_core.analysis import harmonics as H
from vesicle_core.geometry import surface as Sf
from vesicle_core.geometry import ylm as Yl
from vesicle_core.solver import membrane as Mb
from vesicle_core.solver.tension import vertex_mean
from vesicle_core.solver.tension_harmonic import HarmonicSpace, default_l_max, inf_sup


def quality(X, faces):
    a, b, c = X[faces[:, 0]], X[faces[:, 1]], X[faces[:, 2]]
    A = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    s2 = ((b - a) ** 2).sum(1) + ((c - b) ** 2).sum(1) + ((a - c) ** 2).sum(1)
    return 4 * math.sqrt(3) * A / s2


def analyse(path, l_max=None):
    ds = xr.open_dataset(path).load()
    faces = ds.face_node_connectivity.values.astype(np.int64)
    X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
    topo = Mb.Topology(faces, X.shape[1])
    g0 = Mb.geometry(X[0], topo)
    A0 = g0.area
    L = l_max or int(ds.attrs.get("tension_l_used", 0)) or default_l_max(X[0], faces)
    space = HarmonicSpace(X[0], faces, A0, L)
    f = faces
    E = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0)
    lres = Sf.resolvable_l_max(X[0], faces)
    t = ds.time.values
    rows = []
    for k in range(X.shape[0]):
        g = Mb.geometry(X[k], topo)
        e = g.area / A0 - 1
        ec = space.project_faces(e)
        w = A0 / A0.sum()
        q = quality(X[k], faces)
        s = ds.face_tension.values[k].astype(float)
        tv = vertex_mean(s, g, topo)
        rms = np.sqrt(np.mean(tv**2))
        cb = np.sqrt(np.mean((tv[E[:, 0]] - tv[E[:, 1]]) ** 2)) / rms if rms > 0 else 0.0
        qd = H.quadrature(X[k], faces, rule="centroid")
        cl = Yl.project(s, qd.theta, qd.phi, qd.weights, lres)
        pw = (np.abs(cl) ** 2).sum(axis=1) / (4 * np.pi)
        ww = qd.weights / qd.weights.sum()
        var = np.sum(ww * s**2) - np.sum(ww * s) ** 2
        beyond = max(0.0, 1 - pw[1:].sum() / var) if var > 0 else 0.0
        rows.append((t[k], math.sqrt(np.sum(w * ec**2)), np.abs(ec).max(), math.sqrt(np.mean(e**2)), np.abs(e).max(),
                     q.min(), np.median(q), cb, beyond))
    r = np.array(rows)
    after = r[:, 0] >= 0
    out = {"path": path, "L": L, "constrained_strain_rms": r[:, 1].max(), "constrained_strain_max": r[:, 2].max(),
           "triangle_strain_rms": r[:, 3].max(), "triangle_strain_max": r[:, 4].max(),
           "quality_min": r[:, 5].min(), "quality_median_min": r[:, 6].min(), "quality_median_first": r[0, 6],
           "checkerboard_worst_after": r[after, 7].max(), "checkerboard_median_after": float(np.median(r[after, 7])),
           "beyond_resolvable_max": r[after, 8].max(), "resolvable_l": lres,
           "cg_mean": ds.attrs.get("cg_iterations_mean", np.nan), "cg_max": ds.attrs.get("cg_iterations_max", np.nan),
           "stokes_solves": ds.attrs.get("stokes_solves", np.nan), "steps": ds.attrs.get("steps", np.nan)}
    return out, r


def physics(path, ref):
    from vesicle_core.analysis.spectra import spectra_from_trajectory

    specs = []
    for p in (ref, path):
        with xr.open_dataset(p) as ds:
            specs.append(spectra_from_trajectory(ds.load()))
    a, b = specs
    d_ref = a.Delta_l.sel(l=2).sel(time=slice(0.0, 1.0))
    d2 = b.Delta_l.sel(l=2).interp(time=d_ref.time)
    rel = float(np.sqrt(np.mean((d2 - d_ref) ** 2)) / np.sqrt(np.mean(d_ref**2)))
    return {"l_star": float(b.l_star), "l_star_ref": float(a.l_star), "t_star": float(b.t_star),
            "t_star_ref": float(a.t_star), "l_peak": float(b.l_peak), "l_peak_ref": float(a.l_peak),
            "Delta2_rms_diff": rel}


def inf_sup_table(n_vertices, l_list):
    from vesicle_core.geometry import mesh as M

    head = " ".join(f"{'L=' + str(L):>8}" for L in l_list)
    print(f"{'vertices':>8} {'triangles':>9} {'edge/R':>7} {'triangle':>9} " + head)
    for nv in n_vertices:
        m = M.make_vesicle("quasiuniform", n_vertices=nv, axes=(1.0, 0.8, 1.0))
        X, f = m.vertices, m.faces
        e = np.linalg.norm(X[f[:, [1, 2, 0]]] - X[f], axis=2).mean()
        topo = Mb.Topology(f, X.shape[0])
        A0 = Mb.geometry(X, topo).area
        tri = inf_sup(X, f) if f.shape[0] <= 6000 else float("nan")
        vals = []
        for L in l_list:
            if (L + 1) ** 2 > f.shape[0]:
                vals.append(float("nan"))
                continue
            sp = HarmonicSpace(X, f, A0, L, check=False)
            vals.append(inf_sup(X, f, sp.B))
        print(f"{nv:>8} {f.shape[0]:>9} {e:>7.4f} {tri:>9.4f} " + " ".join(f"{v:>8.4f}" for v in vals), flush=True)


def conditioning(path, frames, N):
    """Condition number of the harmonic operator A = dt B^T D M D^T B + G / Lambda at trajectory frames (dense, K
    Stokes solves), preconditioned by the mass alone (G / Lambda: the compliance) and by the measured diagonal in l;
    also the measured rho_l against the frame's l."""
    import scipy.linalg as sl

    from vesicle_core.model.run_config import legacy_config
    from vesicle_core.solver.mobility import IBMMobility, IBMSolver
    from vesicle_core.solver.tension_harmonic import HarmonicTensionSolver

    ds = xr.open_dataset(path).load()
    faces = ds.face_node_connectivity.values.astype(np.int64)
    X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
    chi = float(ds.attrs["chi"])
    cfg = legacy_config(chi=chi, N=N, scheme="inextensible", tension_space="harmonic")
    s = IBMSolver(faces, X[0], cfg)
    topo = s.membrane.topo
    A0 = s.membrane.ref.face_area
    space = HarmonicSpace(X[0], faces, A0, int(ds.attrs.get("tension_l_used", 0)) or None)
    mob = IBMMobility(s.coupler, s.stokes)
    lam = float(ds.attrs["Lambda_eff"])
    for t in frames:
        k = int(np.argmin(np.abs(ds.time.values - t)))
        dt = float(ds.dt_tau.values[k])
        x = s.xp.asarray(X[k])
        _, geo = s.forces(x)
        mob.prepare(x)
        ts = HarmonicTensionSolver(mob, topo, space, lam)
        ts.measure_rho(geo)
        A = np.empty((space.K, space.K))
        for j in range(space.K):
            e = np.zeros(space.K)
            e[j] = 1.0
            A[:, j] = ts.operator(e, geo, dt)[0]
        A = 0.5 * (A + A.T)
        ev_c = sl.eigh(A, space.G / lam, eigvals_only=True)
        d = 1.0 / np.sqrt(dt * ts.rho[space.l] + 1.0 / lam)
        P = (space.G / d[:, None]) / d[None, :]
        ev_d = sl.eigh(A, P, eigvals_only=True)
        print(f"gdt {ds.time.values[k]:+.2f} dt {dt:.3g}: cond compliance {ev_c[-1] / ev_c[0]:.3g}, diagonal in l "
              f"{ev_d[-1] / ev_d[0]:.3g} (eigenvalues {ev_d[0]:.3f}..{ev_d[-1]:.3f}); rho_l: "
              + " ".join(f"{r:.3g}" for r in ts.rho), flush=True)


def relaxation(N, n_vertices, ls, l_t_list):
    """Relaxation rate of r = 1 + eps Y_l0 with the local area constraint (relaxation.mode_rate's setting, no flow):
    triangle tension and the harmonic tension up to each l_t, over the theory Gamma_l (eq. 11)."""
    from vesicle_core.validation.relaxation import mode_rate

    cols = ", ".join(f"l_t = {L}" for L in l_t_list)
    print(f"N = {N}, {n_vertices} vertices: rate / theory; columns: clean interface, triangle, {cols}")
    for l in ls:
        row = [mode_rate(l, N, n_vertices, membrane="clean").ratio,
               mode_rate(l, N, n_vertices, membrane="inextensible").ratio]
        row += [mode_rate(l, N, n_vertices, membrane="inextensible", tension_space="harmonic", tension_l_max=L).ratio
                for L in l_t_list]
        print(f"l = {l:>3}: " + " ".join(f"{x:7.3f}" for x in row), flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trajectories", nargs="*")
    ap.add_argument("--l-max", type=int, default=None)
    ap.add_argument("--ref", default=None, help="reference trajectory for l_*, t_*, Delta_2(t)")
    ap.add_argument("--inf-sup", action="store_true")
    ap.add_argument("--n-vertices", type=int, nargs="+", default=[162, 642, 2562])
    ap.add_argument("--l-max-list", type=int, nargs="+", default=[5, 10, 15, 20, 30])
    ap.add_argument("--frames", action="store_true", help="print every frame's row")
    ap.add_argument("--conditioning", type=float, nargs="*", default=None, metavar="GDT",
                    help="dense condition numbers at these frames of the (one) trajectory; needs --N")
    ap.add_argument("--N", type=int, default=64)
    ap.add_argument("--relaxation", type=int, nargs="*", default=None, metavar="L",
                    help="single-mode relaxation rates of these l (with --N, --n-vertices (first), --l-max-list)")
    a = ap.parse_args()
    if a.inf_sup:
        inf_sup_table(a.n_vertices, a.l_max_list)
    if a.relaxation:
        relaxation(a.N, a.n_vertices[0], a.relaxation, a.l_max_list)
        return
    if a.conditioning:
        conditioning(a.trajectories[0], a.conditioning, a.N)
        return
    for p in a.trajectories:
        out, r = analyse(p, a.l_max)
        if a.ref:
            out.update(physics(p, a.ref))
        print(p)
        for k, v in out.items():
            if k != "path":
                print(f"  {k:>28}: {v:.4g}" if not isinstance(v, str) else f"  {k}: {v}")
        if a.frames:
            print("  gdt  c_rms  c_max  t_rms  t_max  q_min  q_med  cb  beyond")
            for row in r:
                print("  " + " ".join(f"{x:.3g}" for x in row))


if __name__ == "__main__":
    main()
