"""The tension operator's eigenmodes at one frame: which modes carry the checkerboard, and what freeing them costs.

Run by hand on a finished inextensible trajectory (one Stokes solve per triangle: minutes at 2562 vertices):
    python studies/tension_modes.py TRAJECTORY.nc --time 0.26

At the frame nearest ``--time`` (gamma_dot t) the dense operator D M D^T of the tension solve is built column by
column (float64) and diagonalised in the metric of the reference areas W: rho_i are the area rates per unit
tension of its W-orthonormal modes q_i, and g_i = dt Lambda rho_i compares each mode's hydrodynamic stiffness over
one step with the compliance W / Lambda (g << 1: the mode is held by the compliance alone). The frame's stored
tension is expanded in these modes. Per band of g the script prints
- how many modes, and the share of the tension's variance (its W-norm, mean removed) they carry;
- the checkerboard measure (rms difference between neighbouring vertices of the vertex-averaged tension, over the
  rms of the whole vertex-averaged tension) of that band alone, and of the tension without every band up to it;
- the band's roughness on the triangle graph (Rayleigh quotient of its graph Laplacian, 0 for a constant, ~5-6 for
  a field alternating between neighbouring triangles);
- its share of the force D^T sigma and of the velocity M D^T sigma (against the vertex velocity of the frame);
- tang / rho: the response of the mode to a tangential slip of the vertices, (I - n n^T) per vertex, against its
  response through the fluid, and the same for a slip filtered by the vertex graph Laplacian (a high-pass): a
  mesh-scale slip could lift only the modes for which these ratios are large compared with the other modes';
- the strain rate that the tension of this band and every band below it holds back, rho_i c_i: if those modes
  were left out of the constraint (cb_wo is the tension without them), their triangle areas would drift at that
  rate, and over the wrinkling phase (0 <= gamma_dot t <= 0.5) by the printed rms / max strain if the rate
  stayed as at this frame.

Feeds docs/history/solver.md, "What the checkerboard is, and why the two criteria conflict on this discretisation".
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import sys

import numpy as np
import scipy.sparse as sp

from vesicle_core.geometry import surface as Sf
from vesicle_core.model.flow import background_velocity
from vesicle_core.solver.tension import TensionSolver, face_D_matrix, face_DT, vertex_mean

# load_case (a trajectory and the float64 solver of its case) is shared with the timing scripts in benchmarks/
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "benchmarks"))
from bench_tension_sources import edges, load_case  # noqa: E402

BANDS = [(0, 0.3), (0.3, 1), (1, 3), (3, 10), (10, 100), (100, np.inf)]


def triangle_laplacian(faces):
    """Graph Laplacian of the triangles, two triangles adjacent when they share an edge (sparse, (F, F))."""
    f = np.asarray(faces)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = np.sort(e, axis=1)
    owner = np.tile(np.arange(len(f)), 3)
    order = np.lexsort((key[:, 1], key[:, 0]))
    pairs = owner[order].reshape(-1, 2)  # a closed mesh: every edge has exactly two triangles
    n = len(f)
    adj = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    adj = (adj + adj.T).tocsr()
    return sp.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj


def analyse(path, time):
    ds, faces, X, cfg, sol, mob = load_case(path)
    topo = sol.membrane.topo
    W = sol.membrane.ref.face_area
    k = int(np.argmin(np.abs(ds.time.values - time)))
    Xk = X[k]
    F, geo = sol.forces(Xk)
    mob.prepare(Xk)
    dt, Lam = float(ds.dt_tau.values[k]), cfg.Lambda_eff
    ts = TensionSolver(mob, topo, W, Lam)
    n = len(W)
    print(f"{path}: frame gamma_dot t = {ds.time.values[k]:.3f}, {X.shape[1]} vertices, {n} triangles, "
          f"dt = {dt:.3g} tau, Lambda = {Lam:.3g}; building D M D^T ({n} Stokes solves)", flush=True)
    A = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1.0
        A[:, j] = ts.operator(e, geo, 1.0)[0] - W * e / Lam
    print(f"asymmetry {np.abs(A - A.T).max() / np.abs(A).max():.1e}", flush=True)
    Wh = W**-0.5
    rho, Q = np.linalg.eigh(0.5 * (A + A.T) * Wh[:, None] * Wh[None, :])
    del A
    s = ds.face_tension.values[k].astype(float)
    c = Q.T @ (np.sqrt(W) * s)
    g = dt * Lam * rho
    mean_mode = np.argmax(np.abs(Q.T @ np.sqrt(W)))  # the mode closest to a uniform tension
    # responses to a tangential slip: |T D^T q|^2 and the vertex-graph high-pass version
    Dm = face_D_matrix(geo, topo)
    V = Xk.shape[0]
    nv = Sf.vertex_normals(Xk, faces)
    Fq = (Dm.T @ (Wh[:, None] * Q)).reshape(V, 3, n)
    Fq -= nv[:, :, None] * np.einsum("vc,vcn->vn", nv, Fq)[:, None, :]
    tang = np.einsum("vcn,vcn->n", Fq, Fq)
    E = edges(faces)
    adj = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(V, V))
    adj = (adj + adj.T).tocsr()
    Lv = (sp.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj) / 6.0
    high = np.einsum("vcn,vcn->n", Fq, np.stack([Lv @ Fq[:, d, :] for d in range(3)], axis=1))
    del Fq
    Lt = triangle_laplacian(faces)
    rough = np.einsum("in,in->n", Q, Lt @ Q)
    # the frame's velocity, for the velocity shares
    u = background_velocity(Xk, float(ds.flow_sign.values[k]) * cfg.chi)
    U = mob.apply(F - face_DT(s, geo, topo)) + u
    Fs = face_DT(s, geo, topo)

    def cb(field):
        tv = vertex_mean(field, geo, topo)
        return np.sqrt(np.mean((tv[E[:, 0]] - tv[E[:, 1]]) ** 2))

    tv = vertex_mean(s, geo, topo)
    rms = np.sqrt(np.mean(tv**2))
    var = np.sum(np.delete(c, mean_mode) ** 2)
    T_wr = 0.5 / cfg.chi  # the wrinkling phase 0 <= gamma_dot t <= 0.5, in tau
    print(f"checkerboard measure of the stored tension {cb(s) / rms:.3f}; mean {s.mean():.1f}, g from {g.min():.3g} "
          f"to {g.max():.3g}")
    print(f"{'band of g':>14} {'modes':>5} {'var':>5} {'cb':>5} {'cb_wo':>5} {'rough':>5} {'force':>5} {'vel':>6} "
          f"{'tang/rho':>8} {'high/rho':>8} {'drift rms / max over the phase':>32}")
    freed = np.zeros(n, bool)
    for lo, hi in BANDS:
        m = (g >= lo) & (g < hi)
        if not m.any():
            continue
        freed |= m
        sb = Wh * (Q[:, m] @ c[m])
        sw = Wh * (Q[:, freed] @ c[freed])
        Fb = face_DT(sb, geo, topo)
        Ub = mob.apply(Fb)
        rate = Wh * (Q[:, freed] @ (rho[freed] * c[freed]))  # strain rate held back by this band and those below
        rest = s - sw
        print(f"{f'[{lo:g}, {hi:g})':>14} {m.sum():5d} {np.sum(c[m & (np.arange(n) != mean_mode)] ** 2) / var:5.2f} "
              f"{cb(sb) / rms:5.2f} {cb(rest) / np.sqrt(np.mean(vertex_mean(rest, geo, topo) ** 2)):5.2f} "
              f"{np.median(rough[m]):5.2f} {np.linalg.norm(Fb) / np.linalg.norm(Fs):5.2f} "
              f"{np.linalg.norm(Ub) / np.linalg.norm(U):6.4f} {np.median(tang[m] / rho[m]):8.3g} "
              f"{np.median(high[m] / rho[m]):8.3g} {np.sqrt(np.mean(rate**2)) * T_wr:15.2e} / "
              f"{np.abs(rate).max() * T_wr:.2e}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trajectory")
    ap.add_argument("--time", type=float, default=0.26, help="gamma_dot t of the frame")
    a = ap.parse_args()
    analyse(a.trajectory, a.time)


if __name__ == "__main__":
    main()
