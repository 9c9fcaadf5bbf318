"""A kernel-overlap preconditioner for the tension solve, against the compliance and the local mobility.

Run by hand:
    python benchmarks/bench_precond_gram.py N N_VERTICES        # e.g. 64 642, 128 2562, 256 10242

M_loc = c J J^T (x) I_3, J the spreading weights (vertex x grid node), c = the IBM self-mobility over the mean
diagonal of J J^T: positive semi-definite by construction, unlike the truncated measured pair mobility
(tension.LocalPreconditioner), which turns indefinite on fine grids. P = dt D M_loc D^T + W / Lambda is LU-factorised
once. Reported: CG iterations from a cold start (cg_tol 1e-6) of one step of the S = 2224 benchmark case
(chi = 268, dt = 3.7e-5 x 64/N) and the wall time of the solve including the factorisation.
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from vesicle_core import mesh as Mm
from vesicle_core.mobility import IBMMobility, IBMSolver, pair_table
from vesicle_core.run_config import RunConfig
from vesicle_core.tension import LocalPreconditioner, TensionSolver, face_D_matrix

N, nv = int(sys.argv[1]), int(sys.argv[2])
m = Mm.make_vesicle("quasiuniform", n_vertices=nv, axes=(1.0, 0.8, 1.0))
s = IBMSolver(m.faces, m.vertices, RunConfig(chi=268.0, N=N, scheme="inextensible"))
X = s.xp.asarray(m.vertices)
F, geo = s.forces(X)
mob = IBMMobility(s.coupler, s.stokes)
topo = s.membrane.topo
Lam = 1.34e7
dt = 3.7e-5 * (64 / N)  # the step shrinks ~ h (tension limit)
tab = pair_table(mob, r_max=3.0)
self_mob = tab.self_mobility
local = LocalPreconditioner(mob, topo, geo.area.copy(), Lam) if N <= 128 else None
mob.prepare(X)
st = s.coupler._stencil
Mp = st.idx.shape[0]
J = sp.csr_matrix((np.asarray(st.w, float).ravel(), (np.repeat(np.arange(Mp), st.idx.shape[1]), np.asarray(st.idx).ravel())), shape=(Mp, N**3))
G = (J @ J.T).tocsr()
c = self_mob / G.diagonal().mean()

class Gram:
    def __init__(self, power=1.0):
        self.lu = None; self.power = power
    def __call__(self, r, geo, dt):
        if self.lu is None:
            D = face_D_matrix(geo, topo)
            Mloc = sp.kron(c * G, sp.identity(3), format="csr")
            P = dt * (D @ Mloc @ D.T) + sp.diags(geo.area / Lam)
            self.lu = spla.splu(P.tocsc())
        return self.lu.solve(np.asarray(r))
    def solve_done(self):
        pass

u_inf = 268.0 * np.c_[-X[:, 0], X[:, 1], 0 * X[:, 2]]
zero = np.zeros(geo.area.shape[0])
print(f"N={N} V={nv} self-mobility {self_mob:.3g}, gram scale {c:.3g}, G nnz/row {G.nnz/Mp:.0f}")
for name, pre in (("compliance", None), ("local", local), ("gram", Gram())):
    if name == "local" and pre is None:
        continue
    ts = TensionSolver(mob, topo, geo.area.copy(), Lam, tol=1e-6, maxiter=2000, local=pre)
    t = time.perf_counter()
    try:
        sigma, _ = ts.solve(geo, F, u_inf, zero, dt, zero)
        print(f"{name:>10}: {ts.last.iterations} iterations, {time.perf_counter()-t:.1f} s", flush=True)
    except Exception as e:
        print(name, "failed", e)
