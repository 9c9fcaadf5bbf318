"""Where the mesh-scale part of the inextensible tension comes from (issue 10's checkerboard criterion).

Run by hand:
    python benchmarks/bench_tension_sources.py sources TRAJECTORY.nc [--times -0.5 0 0.1 0.2 0.3 0.5]
    python benchmarks/bench_tension_sources.py variants [--N 64] [--n-vertices 642] [--cells face vertex]
        [--bending full normal] [--free 0 35 100]

``sources``: the tension solve is linear in its right-hand side dt D (M F + u_inf) + (A - A^0), so at frames of a
finished inextensible run it is solved (cold, cg_tol 1e-9) for each part alone: the bending and volume forces F,
the background flow u_inf and the area error carried from earlier steps. For each part: the standard deviation
of the vertex-averaged tension, its mean, and the checkerboard ratio (rms difference between neighbouring
vertices over the standard deviation; white noise on the mesh gives ~1.4, a smooth field << 1).

``variants``: the S = 2224 benchmark case of bench_schemes.py run with one tension per triangle (the scheme) or per
vertex dual cell, and with the full discrete bending force or its normal projection (the continuum Helfrich force
has no tangential part, so a tangential mesh-scale force would be a discretisation artefact). Reported: the
checkerboard measure over 0 <= gamma_dot t <= 0.5 on the solved tension at every step (worst, median, fraction of
steps above 0.3 of the rms; median over the standard deviation), triangle and dual-cell strains, l_*.
``--free k`` leaves the k weakest patterns of D D^T (the triangle-area patterns that vertex motion changes least,
where the checkerboard lives: studies/tension_modes.py) out of the triangle constraint, to measure what not
holding their areas costs.
Quote timings with what else ran on the machine.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import itertools
import json
import sys
import tempfile

import numpy as np
import xarray as xr

from vesicle_core.analysis.spectra import spectra_from_trajectory
from vesicle_core.geometry import mesh as M
from vesicle_core.model.flow import background_velocity
from vesicle_core.model.run_config import legacy_config
from vesicle_core.solver import integrators as I
from vesicle_core.solver import membrane as B
from vesicle_core.solver.mobility import IBMMobility, IBMSolver
from vesicle_core.solver.simulate import run
from vesicle_core.solver.tension import TensionSolver, dual_areas, face_mean, vertex_mean


def edges(faces):
    f = np.asarray(faces)
    return np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0)


def neighbour_rms(tv, E):
    return float(np.sqrt(np.mean((tv[E[:, 0]] - tv[E[:, 1]]) ** 2)))


# --------------------------------------------------------------------------- sources
def load_case(path):
    """A finished trajectory and the float64 solver of its case: (ds, faces, X (frames, V, 3), cfg, solver,
    mobility); the solver's reference shape is the first frame."""
    ds = xr.open_dataset(path).load()
    faces = ds.face_node_connectivity.values
    X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
    a = ds.attrs
    cfg = legacy_config(chi=float(a["chi"]), N=int(a["N"]), L=float(a["L"]), scheme="inextensible", dtype="float64",
                    kernel=str(a.get("kernel", "peskin4")))
    sol = IBMSolver(faces, X[0], cfg)
    return ds, faces, X, cfg, sol, IBMMobility(sol.coupler, sol.stokes, sol._grid_buf)


def sources(path, times):
    ds, faces, X, cfg, sol, mob = load_case(path)
    mem = sol.membrane
    ts = TensionSolver(mob, mem.topo, mem.ref.face_area, cfg.Lambda_eff, tol=1e-9, maxiter=5000)
    E = edges(faces)
    print(f"{path}: N = {cfg.N}, {X.shape[1]} vertices, chi = {cfg.chi:g}")
    print(f"{'time':>6} {'part':>15} {'std':>8} {'mean':>8} {'nbr/std':>8}")
    for tt in times:
        k = int(np.argmin(np.abs(ds.time.values - tt)))
        F, geo = sol.forces(X[k])
        dt = float(ds.dt_tau.values[k])
        mob.prepare(X[k])
        u = background_velocity(X[k], float(ds.flow_sign.values[k]) * cfg.chi)
        err = geo.area - mem.ref.face_area
        parts = {"all": (F, u, err), "bending+volume": (F, 0 * u, 0 * err), "flow": (0 * F, u, 0 * err),
                 "area error": (0 * F, 0 * u, err), "stored": None}
        for name, rhs in parts.items():
            if rhs is None:
                s = ds.face_tension.values[k].astype(float)
            else:
                s, _ = ts.solve(geo, *rhs, dt, np.zeros(len(faces)))
            tv = vertex_mean(s, geo, mem.topo)
            print(f"{ds.time.values[k]:6.2f} {name:>15} {tv.std():8.0f} {tv.mean():8.0f} "
                  f"{neighbour_rms(tv, E) / tv.std():8.2f}", flush=True)


# --------------------------------------------------------------------------- variants
class FreedTensionSolver(TensionSolver):
    """The tension solve with the ``k`` weakest patterns of D D^T (the triangle-area patterns that vertex motion
    changes least) left out of the constraint: the CG runs on the complement (operator, preconditioner and
    residual projected by P = I - Z Z^T), so those patterns' areas are not held and drift. Z is recomputed every
    ``refresh`` solves (dense eigh: small meshes only)."""

    def __init__(self, *args, k=0, refresh=10, **kw):
        super().__init__(*args, **kw)
        self.k, self.refresh, self._n, self.Z = int(k), int(refresh), 0, None

    def _P(self, x):
        return x - self.Z @ (self.Z.T @ x)

    def operator(self, p, geo, dt):
        Ap, q = super().operator(p, geo, dt)
        return self._P(Ap), q

    def _precondition(self, r, geo, dt):
        return self._P(super()._precondition(self._P(r), geo, dt))

    def strain_rms(self, r):
        return super().strain_rms(self._P(r))

    def solve(self, geo, F, u_inf, area_error, dt, sigma0):
        from vesicle_core.solver.tension import face_D_matrix

        if self.Z is None or self._n % self.refresh == 0:
            D = face_D_matrix(geo, self.topo)
            _, vec = np.linalg.eigh((D @ D.T).toarray())
            self.Z = vec[:, : self.k]
        self._n += 1
        return super().solve(geo, F, u_inf, area_error, dt, self._P(sigma0))


def make_integrator(cells, bending, record, free=0):
    """The inextensible integrator with the tension on vertex dual cells and/or the bending force projected on
    the vertex normals; ``record`` collects (phase, t, nbr/rms, nbr/std) of the solved tension at every step."""

    class Variant(I.Inextensible):
        def __init__(self, solver, dt_bending):
            super().__init__(solver, dt_bending)
            mem = solver.membrane
            self.E = edges(np.asarray(mem.topo.faces))
            if free:
                self.tension = FreedTensionSolver(self.mobility, mem.topo, mem.ref.face_area, self.cfg.Lambda_eff,
                                                  tol=self.cfg.cg_tol, maxiter=self.cfg.cg_maxiter, k=free)
            if cells == "vertex":
                self.A0v = dual_areas(B.geometry(solver.X0, mem.topo), mem.topo)
                self.tension = TensionSolver(self.mobility, mem.topo, self.A0v, self.cfg.Lambda_eff,
                                             tol=self.cfg.cg_tol, maxiter=self.cfg.cg_maxiter, cells="vertex")

        def _face(self, sigma):
            return face_mean(sigma, self.solver.membrane.topo) if cells == "vertex" else sigma

        def sigma_mean(self, state, geo):
            if state.sigma is None:
                return 0.0
            return float(np.sum(self._face(state.sigma) * geo.area) / np.sum(geo.area))

        def next_dt(self, state, geo):
            sv = state.sigma
            if sv is not None:
                state.sigma = self._face(sv)  # the stability limits read triangle tensions
            try:
                return super().next_dt(state, geo)
            finally:
                state.sigma = sv

        def step(self, state, X, F, geo, dt, rate):
            mem = self.solver.membrane
            if bending == "normal":
                n = vertex_normals(geo, mem.topo)
                Fb = -mem.topo.scatter(B._bending_corner_gradient(geo, mem.topo, mem.kappa, mem.area_model)).T
                F = F - Fb + (Fb * n).sum(1, keepdims=True) * n
            if cells == "face":
                dX = super().step(state, X, F, geo, dt, rate)
            else:
                if state.sigma is None:
                    state.sigma = np.zeros(mem.topo.n_vertices)
                self.mobility.prepare(X)
                guess = state.sigma
                if state.sigma_prev is not None:
                    h_a, h_b = state.dt_steps
                    guess = state.sigma + (h_b / h_a) * (state.sigma - state.sigma_prev)
                u_inf = I.background_velocity(X, rate) if self.cfg.chi > 0 else 0.0
                sigma, U = self.tension.solve(geo, F, u_inf, dual_areas(geo, mem.topo) - self.A0v, dt, guess)
                state.sigma_prev, state.sigma = state.sigma, sigma
                state.dt_steps = (state.dt_steps[-1] if state.dt_steps else dt, dt)
                self.iterations.append(self.tension.last.iterations)
                dX = U * dt
            tv = state.sigma if cells == "vertex" else vertex_mean(state.sigma, geo, mem.topo)
            d = neighbour_rms(tv, self.E)
            record.append((state.phase, state.t, d / np.sqrt(np.mean(tv**2)), d / tv.std()))
            return dX

        def face_tension(self, state, geo):
            if state.sigma is None:
                return super().face_tension(state, geo)
            return self._face(state.sigma)

    return Variant


def vertex_normals(geo, topo):
    acc = np.zeros((topo.n_vertices, 3))
    w = (geo.normal * geo.area).T
    for c in range(3):
        np.add.at(acc, np.asarray(topo.faces)[:, c], w)
    return acc / np.linalg.norm(acc, axis=1, keepdims=True)


def variants(a):
    sys.path.insert(0, os.path.dirname(__file__))
    from bench_schemes import inextensibility

    mesh = M.make_vesicle("quasiuniform", n_vertices=a.n_vertices, axes=(1.0, 0.8, 1.0))
    orig_init = IBMSolver.__init__

    def init(self, faces, X0, cfg):  # the variants need the reference positions for the dual-cell areas
        orig_init(self, faces, X0, cfg)
        self.X0 = np.asarray(X0, dtype=float)

    IBMSolver.__init__ = init
    with tempfile.TemporaryDirectory() as d:
        for cells, bending, free in itertools.product(a.cells, a.bending, a.free):
            if True:
                record = []
                I.SCHEMES["inextensible"] = make_integrator(cells, bending, record, free)
                cfg = legacy_config(chi=a.chi, N=a.N, stretch=1.0, t_end=1.0, output_every=0.02, scheme="inextensible",
                                dtype="float64" if a.N <= 64 else "float32")
                path = run(mesh, cfg, os.path.join(d, f"{cells}_{bending}_{free}"), progress=False)
                with xr.open_dataset(path) as ds:
                    ds = ds.load()
                r = np.array([x[1:] for x in record if x[0] == "relax"], float)
                t = (r[:, 0] - r[0, 0]) * cfg.chi
                w = (t >= 0) & (t <= 0.5)
                ie = inextensibility(ds)
                row = {"cells": cells, "bending": bending, "free": free, "steps": int(ds.attrs["steps"]),
                       "checkerboard_worst": float(r[w, 1].max()), "checkerboard_median": float(np.median(r[w, 1])),
                       "fraction_over_0.3": float(np.mean(r[w, 1] > 0.3)),
                       "nbr_over_std_median": float(np.median(r[w, 2])),
                       **{k: float(ie[k]) for k in ("face_strain_rms", "face_strain_max", "vertex_strain_rms",
                                                    "vertex_strain_max")},
                       "l_star": float(spectra_from_trajectory(ds).l_star)}
                print(json.dumps(row), flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    s = sub.add_parser("sources")
    s.add_argument("trajectory")
    s.add_argument("--times", type=float, nargs="+", default=[-0.5, 0.0, 0.1, 0.2, 0.3, 0.5])
    v = sub.add_parser("variants")
    v.add_argument("--N", type=int, default=64)
    v.add_argument("--n-vertices", type=int, default=642)
    v.add_argument("--chi", type=float, default=267.8)
    v.add_argument("--cells", nargs="+", default=["face", "vertex"], choices=["face", "vertex"])
    v.add_argument("--bending", nargs="+", default=["full", "normal"], choices=["full", "normal"])
    v.add_argument("--free", nargs="+", type=int, default=[0],
                   help="leave the k weakest patterns of D D^T out of the triangle constraint (face cells)")
    a = ap.parse_args()
    if a.what == "sources":
        sources(a.trajectory, a.times)
    else:
        variants(a)


if __name__ == "__main__":
    main()
