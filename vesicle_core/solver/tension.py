"""Local membrane tension from the linearised local area constraint, solved every time step.

The membrane is locally inextensible: the area of every cell (each triangle by default, or each
vertex's barycentric dual cell A_i = 1/3 sum_{l in T(i)} A_l) keeps its reference value A^0 up to a
compliance sigma / Lambda (Lambda: the area-stretch modulus, kappa/R^2). One tension per cell acts
through the force F_sigma = -D^T sigma, D = dA/dX the gradient of the cell areas: this is eq. (2)-(4),
E_sigma = int sigma dA, with sigma a field solved for instead of the penalty (A5). Over a step dt with
the velocity U = M (F - D^T sigma) + u_inf, the linearised area change A + dt D U - A^0 = W sigma / Lambda
(W = diag(A^0)) gives the symmetric positive definite system

    (dt D M D^T + W / Lambda) sigma = dt D (M F + u_inf) + (A - A^0),

whose right-hand side also corrects the area error left by the previous step, so no drift accumulates.
The step's velocity comes out of the solve: U = U_0 - sum_k alpha_k M D^T p_k (no extra Stokes solve).

Solver: conjugate gradients, warm-started (the integrator extrapolates the last two tensions), with M
applied matrix-free (one Stokes solve per iteration). Preconditioners: the compliance W / Lambda (default), or
:class:`LocalPreconditioner`, dt D M_loc D^T + W / Lambda with the IBM's measured near-field mobility M_loc,
LU-factorised every few steps. Convergence is measured in strain: rms |r| / A^0 <= tol. A solve that does not
converge within ``maxiter`` iterations raises NumericalInstability: never a silent step.

Conditioning (measured, benchmarks/bench_tension.py; N = 64, 642 vertices, edge ~ 2h, Lambda = 1.3e7,
dt = 3.7e-5): in the eigenbasis of the surface Laplacian the operator is a band-pass in the wavenumber q -- the
area rate per unit tension rises like ~0.1 q at small q, peaks near q h ~ 0.5 and falls to ~0 at the mesh scale,
where the kernel cannot see tension waves; uniform tension moves nothing. With the compliance as preconditioner
the condition number is ~300; with the local mobility (pairs within 3h) 47. Functions of the surface Laplacian
alone do no better than 145 (the operator mixes Laplacian modes), and sparse probing of the operator is
indefinite. Prior art: Veerapaneni, Gueyffier, Zorin & Biros, JCP 228 (2009) (a tension solve each step for
vesicles); Kallemov, Bhalla, Griffith & Donev, CAMCoS 11 (2016) (IB constraints preconditioned by a local
mobility).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, NumericalInstability
from ..xp import to_float, to_numpy

CELLS = ("face", "vertex")


# --------------------------------------------------------------------------- cells and their area gradient
def dual_areas(geo, topo):
    """Barycentric dual-cell areas A_i = 1/3 sum of the adjacent triangle areas, (V,)."""
    xp = topo.xp
    return topo.scatter(xp.broadcast_to(geo.area / 3.0, (3, geo.area.shape[0])))


def face_mean(sigma, topo):
    """Triangle value of a vertex field: the mean over its 3 corners, (F,)."""
    return sigma[topo.fT].mean(axis=0)


def vertex_mean(sigma_face, geo, topo):
    """Area-weighted vertex average of a triangle field, (V,) (for smooth renders and diagnostics)."""
    xp = topo.xp
    num = topo.scatter(xp.broadcast_to(sigma_face * geo.area, (3, geo.area.shape[0])))
    return num / topo.scatter(xp.broadcast_to(geo.area, (3, geo.area.shape[0])))


def _face_rates(U, geo, topo):
    xp = topo.xp
    Uc = xp.ascontiguousarray(U.T)[:, topo.fT]  # (3, 3, F) velocity at the corners
    return (geo.grad_area * Uc).sum(axis=(0, 1))  # dA_l/dt per triangle


def face_DT(sigma, geo, topo):
    """D^T sigma (V, 3) = sum_l sigma_l dA_l/dX for triangle cells: minus the tension force."""
    return topo.scatter(sigma * geo.grad_area).T


def face_D(U, geo, topo):
    """D U (F,) = dA_l/dt for triangle cells and vertex velocities U (V, 3)."""
    return _face_rates(U, geo, topo)


def vertex_DT(sigma, geo, topo):
    """D^T sigma (V, 3) for dual cells = sum_l sigma_bar_l dA_l/dX, sigma_bar_l the corner mean."""
    return face_DT(face_mean(sigma, topo), geo, topo)


def vertex_D(U, geo, topo):
    """D U (V,): rate of change of the dual-cell areas."""
    xp = topo.xp
    rate = _face_rates(U, geo, topo)
    return topo.scatter(xp.broadcast_to(rate / 3.0, (3, rate.shape[0])))


def cell_areas(geo, topo, cells):
    return geo.area if cells == "face" else dual_areas(geo, topo)


# --------------------------------------------------------------------------- the solve
@dataclass
class SolveInfo:
    iterations: int
    residual: float  # rms strain of the final residual
    residual0: float  # rms strain of the warm-start residual


def pcg(x, U, r, operator, precondition, dot, residual, tol, maxiter):
    """Preconditioned conjugate gradients on the tension unknowns x, carrying the membrane velocity U along.

    ``operator(p)`` returns (A p, q) with q the velocity change per unit p (so that U - alpha q stays the velocity of
    x + alpha p), ``precondition(r)`` applies P^{-1}, ``dot`` is the inner product, ``residual(r)`` the rms strain
    compared with ``tol``. x, U and r are updated in place. Returns (x, U, iterations, residual, start residual);
    raises NumericalInstability when a search direction is not positive or ``maxiter`` is reached. Shared by the
    per-triangle and the harmonic tension (:mod:`vesicle_core.solver.tension_harmonic`).
    """
    res0 = res = residual(r)
    it = 0
    if res <= tol:
        return x, U, it, res, res0
    z = precondition(r)
    p = z
    rz = dot(r, z)
    while True:
        Ap, q = operator(p)
        pAp = dot(p, Ap)
        if not (pAp > 0 and np.isfinite(pAp)):
            raise NumericalInstability(f"tension solve: operator not positive along a search direction "
                                       f"(p.Ap = {pAp:.3g}) at iteration {it}")
        alpha = rz / pAp
        x += alpha * p
        U -= alpha * q
        r -= alpha * Ap
        it += 1
        res = residual(r)
        if res <= tol:
            return x, U, it, res, res0
        if it >= maxiter or not np.isfinite(res):
            raise NumericalInstability(
                f"tension solve did not converge: rms strain residual {res:.3g} > cg_tol {tol:g} after "
                f"{it} CG iterations (start {res0:.3g}); lower dt or raise cg_maxiter")
        z = precondition(r)
        rz_new = dot(r, z)
        p = z + (rz_new / rz) * p
        rz = rz_new


class TensionSolver:
    """PCG for (dt D M D^T + W / Lambda) sigma = rhs with M = ``mobility`` (see the module docstring).

    mobility: an object with ``apply(F) -> U`` at the prepared configuration (IBMMobility);
    A0: reference cell areas (W); cells: "face" (one tension per triangle) or "vertex" (dual cells).
    """

    def __init__(self, mobility, topo, A0, Lambda, tol=1e-6, maxiter=200, cells="face", local=None):
        if cells not in CELLS:
            raise ConfigError(f"cells must be one of {CELLS}, got {cells!r}")
        if not Lambda > 0:
            raise ConfigError(f"Lambda (area-stretch modulus) must be > 0 for the tension solve, got {Lambda!r}")
        self.mobility = mobility
        self.topo = topo
        self.xp = topo.xp
        self.A0 = A0
        self.Lambda = float(Lambda)
        self.tol = float(tol)
        self.maxiter = int(maxiter)
        self.cells = cells
        self.DT, self.D = (face_DT, face_D) if cells == "face" else (vertex_DT, vertex_D)
        self._pinv = self.Lambda / A0  # the compliance preconditioner W^{-1} Lambda
        self.local = local  # LocalPreconditioner or None (compliance only)
        self.last = SolveInfo(0, 0.0, 0.0)

    def _precondition(self, r, geo, dt):
        if self.local is not None:
            z = self.local(r, geo, dt)
            if z is not None:
                return z
        return self._pinv * r

    def operator(self, p, geo, dt):
        """(A p, M D^T p) for a cell field p; A = dt D M D^T + W / Lambda."""
        q = self.mobility.apply(self.DT(p, geo, self.topo))
        return dt * self.D(q, geo, self.topo) + self.A0 * p / self.Lambda, q

    def strain_rms(self, r):
        xp = self.xp
        return to_float(xp.sqrt(xp.mean((r / self.A0) ** 2)))

    def solve(self, geo, F, u_inf, area_error, dt, sigma0):
        """Tension sigma and velocity U (V, 3) of one step (see _solve); with the local preconditioner, a solve
        that does not converge is repeated once with the compliance preconditioner before giving up."""
        if self.local is None:
            return self._solve(geo, F, u_inf, area_error, dt, sigma0)
        try:
            return self._solve(geo, F, u_inf, area_error, dt, sigma0)
        except NumericalInstability:
            local, self.local = self.local, None
            self.fallbacks = getattr(self, "fallbacks", 0) + 1
            try:
                return self._solve(geo, F, u_inf, area_error, dt, sigma0)
            finally:
                self.local = local
                local.solve_done()

    def _solve(self, geo, F, u_inf, area_error, dt, sigma0):
        """Tension sigma and velocity U (V, 3) of one step; the mobility must be prepared at geo's positions.

        F: the other Lagrangian forces (bending, volume); u_inf: background velocity at the vertices (or 0);
        area_error: A - A^0 per cell. Raises NumericalInstability when PCG does not converge.
        """
        xp = self.xp
        sigma = xp.array(sigma0, dtype=xp.float64, copy=True)
        U = self.mobility.apply(F - self.DT(sigma, geo, self.topo)) + u_inf
        r = dt * self.D(U, geo, self.topo) + area_error - self.A0 * sigma / self.Lambda
        sigma, U, it, res, res0 = pcg(sigma, U, r, lambda p: self.operator(p, geo, dt),
                                      lambda r: self._precondition(r, geo, dt), lambda a, b: to_float(xp.sum(a * b)),
                                      self.strain_rms, self.tol, self.maxiter)
        if self.local is not None:
            self.local.solve_done()
        self.last = SolveInfo(it, res, res0)
        return sigma, U


def face_D_matrix(geo, topo):
    """D for triangle cells as a scipy.sparse CSR matrix (F, 3V): row l holds dA_l/dX at its 3 corners."""
    import scipy.sparse as sp

    fT = to_numpy(topo.fT)
    gA = to_numpy(geo.grad_area)  # (3 k, 3 c, F)
    nF = fT.shape[1]
    rows = np.broadcast_to(np.arange(nF)[None, None, :], (3, 3, nF))  # (corner, component, face)
    cols = np.broadcast_to(3 * fT[:, None, :] + np.arange(3)[None, :, None], (3, 3, nF))
    vals = np.transpose(gA, (1, 0, 2))
    return sp.csr_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(nF, 3 * topo.n_vertices))


def smallest_eigenvalue(A) -> float:
    """Smallest eigenvalue of a sparse symmetric matrix (Lanczos, 1e-3 relative; dense below 600 rows). If
    Lanczos does not converge, Gershgorin's lower bound min_i (a_ii - sum_j!=i |a_ij|): never above lam_min."""
    import scipy.sparse.linalg as spla

    if A.shape[0] < 600:
        return float(np.linalg.eigvalsh(A.toarray())[0])
    try:
        return float(spla.eigsh(A, k=1, which="SA", tol=1e-3, return_eigenvectors=False)[0])
    except spla.ArpackNoConvergence:
        d = A.diagonal()
        return float(np.min(2 * d - np.asarray(abs(A).sum(axis=1)).ravel()))


class LocalPreconditioner:
    """P = dt D M_loc D^T + W / Lambda, LU-factorised, with M_loc the IBM's near-field mobility.

    M_loc: the measured self and pair mobility of the IBM (mobility.pair_table) for vertex pairs closer than
    ``r_cut`` (default 3 h), tapered by (1 - (r/r_cut)^2)^2 (mobility.local_mobility_matrix; Kallemov, Bhalla,
    Griffith & Donev, CAMCoS 11 (2016)). Refactorised every ``refresh`` solves or when dt leaves [0.7, 1.4] of the
    dt it was built for. Measured on the dense operator (N = 64, 642 vertices, edge ~ 2h): condition number 47
    with r_cut = 3h and 28 with 4h, against 298 for the compliance alone. The truncated mobility stays positive
    definite only for short cut-offs: smallest eigenvalue +0.0065 at 3h but -0.0062 at 4h (N = 128, 2562
    vertices, self-mobility 1.05), and with 4h the CG stalls there; with edge ~ h it is indefinite even at 1.5h.
    At N = 256 (10242 vertices) it is indefinite with 3h too (smallest eigenvalue -0.020 against a self-mobility
    of 2.13), and the CG with it stalled. So each build shifts M_loc by s I, s = max(0, ``margin`` f(0) - lam_min)
    with lam_min its smallest eigenvalue (Lanczos): P is then positive definite on every grid, and the shift
    barely touches it where M_loc was definite (N = 128, cold step: 21 iterations unshifted, 21-22 with shifts up
    to 5% of f(0)). A preconditioned residual with r.z <= 0 falls back to the compliance preconditioner for that
    iteration, and TensionSolver repeats an unconverged solve once with the compliance preconditioner.
    Construct it before preparing the mobility for a step: measuring the pair table replaces the stencil.
    """

    def __init__(self, mobility, topo, A0, Lambda, r_cut_h=3.0, refresh=10, margin=0.02):
        from .mobility import pair_table

        self.topo = topo
        self.W = to_numpy(A0)
        self.Lambda = float(Lambda)
        self.table = pair_table(mobility, r_max=r_cut_h)
        self.r_cut = r_cut_h * mobility.grid.h
        self.refresh = int(refresh)
        self.xp = topo.xp
        self._lu = None
        self._dt = None
        self._uses = 0
        self.factorisations = 0
        self.seconds = 0.0  # wall time spent building, factorising and applying P (cost accounting)
        self.margin = float(margin)
        self.shift = 0.0  # the last build's diagonal shift of M_loc (0 where it was definite with margin)

    def _build(self, geo, dt):
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        from .mobility import local_mobility_matrix

        X = to_numpy(geo.P)  # corner positions -> vertices
        fT = to_numpy(self.topo.fT)
        pos = np.empty((self.topo.n_vertices, 3))
        for c in range(3):
            pos[fT[c]] = X[:, c].T
        D = face_D_matrix(geo, self.topo)
        M_loc = local_mobility_matrix(pos, self.table, r_cut=self.r_cut)
        self.shift = max(0.0, self.margin * self.table.self_mobility - smallest_eigenvalue(M_loc))
        if self.shift > 0:
            M_loc = M_loc + self.shift * sp.identity(M_loc.shape[0], format="csr")
        P = dt * (D @ M_loc @ D.T) + sp.diags(self.W / self.Lambda)
        # P is symmetric positive definite (M_loc shifted where needed): a symmetric fill-reducing ordering with
        # diagonal pivots has ~2/3 of COLAMD's fill and factorises ~5x faster (0.15 s against 0.70 s at 5120
        # triangles, each solve 2.0 ms against 6.6 ms); the factorisation was most of this preconditioner's cost
        P = P.tocsc()
        try:
            self._lu = spla.splu(P, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError:  # a zero pivot (round-off despite the shift): factorise with partial pivoting
            self._lu = spla.splu(P)
        self._dt = dt
        self._uses = 0
        self.factorisations += 1

    def __call__(self, r, geo, dt):
        t0 = time.perf_counter()
        try:
            if self._lu is None or self._uses >= self.refresh or not 0.7 <= dt / self._dt <= 1.4:
                self._build(geo, dt)
            rh = to_numpy(r)
            z = self._lu.solve(rh)
        finally:
            self.seconds += time.perf_counter() - t0
        if not float(rh @ z) > 0:
            return None
        return self.xp.asarray(z)

    def solve_done(self):
        self._uses += 1
