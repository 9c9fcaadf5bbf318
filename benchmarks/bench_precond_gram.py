"""A kernel-overlap preconditioner for the tension solve, against the compliance and the local mobility.

Run by hand:
    python benchmarks/bench_precond_gram.py N N_VERTICES        # e.g. 64 642, 128 2562, 256 10242

M_loc = c J J^T (x) I_3, J the spreading weights (vertex x grid node), c = the IBM self-mobility over the mean
diagonal of J J^T: positive semi-definite by construction, unlike the truncated measured pair mobility
(tension.LocalPreconditioner), which turns indefinite on fine grids. P = dt D M_loc D^T + W / Lambda is LU-factorised
once. Reported: CG iterations from a cold start (cg_tol 1e-6) of one step of the S = 2224 benchmark case
(chi = 268, dt = 3.7e-5 x 64/N) and the wall time of the solve including the factorisation.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from vesicle_core.errors import NumericalInstability
from vesicle_core.geometry import mesh as Mm
from vesicle_core.model.run_config import legacy_config
from vesicle_core.solver.mobility import IBMMobility, IBMSolver, pair_table
from vesicle_core.solver.tension import LocalPreconditioner, TensionSolver, face_D_matrix

LAMBDA = 1.34e7  # 5e4 chi at S = 2224


class KernelOverlap:
    """P = dt D (c J J^T (x) I_3) D^T + W / Lambda, factorised at the first call."""

    def __init__(self, G, c, topo):
        self.G, self.c, self.topo, self.lu = G, c, topo, None

    def __call__(self, r, geo, dt):
        if self.lu is None:
            D = face_D_matrix(geo, self.topo)
            M_loc = sp.kron(self.c * self.G, sp.identity(3), format="csr")
            self.lu = spla.splu((dt * (D @ M_loc @ D.T) + sp.diags(geo.area / LAMBDA)).tocsc())
        return self.lu.solve(np.asarray(r))

    def solve_done(self):
        pass


def main(N, n_vertices):
    m = Mm.make_vesicle("quasiuniform", n_vertices=n_vertices, axes=(1.0, 0.8, 1.0))
    s = IBMSolver(m.faces, m.vertices, legacy_config(chi=268.0, N=N, scheme="inextensible"))
    X = s.xp.asarray(m.vertices)
    F, geo = s.forces(X)
    mob = IBMMobility(s.coupler, s.stokes)
    topo = s.membrane.topo
    dt = 3.7e-5 * (64 / N)  # the step shrinks ~ h (tension limit)
    self_mobility = pair_table(mob, r_max=3.0).self_mobility
    # the local preconditioner measures its pair table before the stencil of X is prepared
    local = LocalPreconditioner(mob, topo, geo.area.copy(), LAMBDA) if N <= 128 else None
    mob.prepare(X)
    st = s.coupler._stencil
    n = st.idx.shape[0]
    rows = np.repeat(np.arange(n), st.idx.shape[1])
    J = sp.csr_matrix((np.asarray(st.w, float).ravel(), (rows, np.asarray(st.idx).ravel())), shape=(n, N**3))
    G = (J @ J.T).tocsr()
    c = self_mobility / G.diagonal().mean()
    u_inf = 268.0 * np.c_[-X[:, 0], X[:, 1], 0 * X[:, 2]]
    zero = np.zeros(geo.area.shape[0])
    print(f"N = {N}, {n_vertices} vertices: self-mobility {self_mobility:.3g}, overlap scale {c:.3g}, "
          f"{G.nnz / n:.0f} overlapping vertices per vertex")
    for name, pre in (("compliance", None), ("local", local), ("kernel overlap", KernelOverlap(G, c, topo))):
        if name == "local" and pre is None:
            print(f"{name:>15}: not run above N = 128 (it stalls there, docs/history/solver.md)")
            continue
        ts = TensionSolver(mob, topo, geo.area.copy(), LAMBDA, tol=1e-6, maxiter=2000, local=pre)
        t = time.perf_counter()
        try:
            ts.solve(geo, F, u_inf, zero, dt, zero)
            print(f"{name:>15}: {ts.last.iterations} iterations, {time.perf_counter() - t:.1f} s", flush=True)
        except NumericalInstability as exc:
            print(f"{name:>15}: failed ({exc})")


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]))
