r"""The mesh-scale bending and tension stiffness taken off the step: a linearly stabilised inextensible scheme (run
parameter ``stiffness: implicit``; not the default).

Operator. On the vertex normals n_k, with C the cotan Laplacian's stiffness matrix
(C_ij = -(cot a_ij + cot b_ij) / 2 on an edge, C_ii = -sum_j C_ij) and M the vertices' Voronoi areas,
-Delta_S ~ M^{-1} C, and

    P dX = n [alpha (M^{-1} C)^2 + beta M^{-1} C] (n . dX)        (tangential components untouched)

On a sphere of radius R a normal displacement s Y_lm is an eigenfunction of -Delta_S with eigenvalue l(l+1) / R^2,
so the continuum symbol of P is alpha (l(l+1))^2 / R^4 + beta l(l+1) / R^2 (``tests/solver/test_implicit_stiffness.py``
checks the discrete operator against it on an icosphere). The bending force of the Helfrich energy linearised about
a sphere has the symbol kappa l(l+1)(l-1)(l+2) / R^4 (eq. 11's Gamma_l before the mobility), the same (-Delta)^2 at
large l, and a tension sigma adds sigma l(l+1) / R^2 (eq. 11's A_l sigma): P has the shape of the stiff part of the
force, without its mobility. The tension's part matters: on the default job's stretched shape at 128^3 the stiffest
mode of the step (l ~ 45-47, along the normals) is bending and tension together, 1.65x (S = 553) and 3.7x (S = 2224)
the bending alone (benchmarks/bench_tension_stiffness.py).

Splitting (linearly stabilised forward Euler; the small-scale decomposition's idea, Hou, Lowengrub & Shelley, J.
Comput. Phys. 114 (1994) 312, and for the immersed boundary Hou & Shi, J. Comput. Phys. 227 (2008) 8968): with U(X)
the inextensible scheme's velocity (tension solved, flow and background included),

    (X^{n+1} - X^n) / dt = U(X^n) - P (X^{n+1} - X^n)   <=>   (I + dt P) dX = dt U(X^n)

P is added implicitly and, through dX ~ dt U, subtracted explicitly to O(dt): the step stays first order and
consistent, and a mode of rate -lam (lam > 0) and symbol p amplifies by g = 1 - dt lam / (1 + dt p). It is stable for
dt (lam - 2 p) <= 2: where p >= lam / 2 (the stiff mesh-scale modes, once alpha is sized for them) for every dt.
A wrinkle's growth rate r becomes r / (1 + dt p(l)): the splitting's error there is dt p(l), which is why P must be
small at the wrinkles' l. Only the normal part is solved for: (I + dt P) s' = s, multiplied by M into the symmetric
positive definite (M + dt (alpha C M^{-1} C + beta C)) s' = M s, by conjugate gradients (diagonal preconditioner,
20-60 iterations): no Stokes solve.

Sizing. beta = r_sigma / (2 l_c (l_c + 1)), r_sigma = 2 sigma_max / (c h) the tension formula's rate
(integrators.TENSION_STABILITY) at the largest positive tension (a compressive tension adds no stiffness to the stiff
mode: measured, it lowers it), so that beta (-L) reaches half the tension's rate at l_c (``stiffness_tension: false``
leaves it out). alpha = lam_0 / (2 (l_c (l_c + 1))^2), lam_0 the start's explicit stiffest rate
(step_size.stiffest_mode):
the stabilisation reaches half the stiffest rate at l_c (``stiffness_l``, default half the grid's l, ceil(pi R / h)
/ 2), so every mode from l_c up, where the rate has saturated at lam_0 (docs/history/solver.md: the stiff modes are
l ~ 40-96 at 128^3), is stable at any dt. Below l_c, P falls as l^4 while the rate falls as ~l^3, so a residue of
explicit stiffness remains, and the step-size rule measures it rather than assuming it:

Step size. The bending limit is the stability limit of the step actually taken. For a step length d, the Arnoldi
iteration of step_size runs on K_d = (I + d P)^{-1} J_s (J_s = M d(F - D^T sigma)/dX at the last step's tension
sigma held frozen, the explicit scheme's linearisation with the tension's stiffness; one Stokes solve and one sparse
solve per product); the step is stable while d |mu|max(K_d) <= 2. d |mu|max(K_d) increases with d, so
d <- 2 / |mu|max(K_d) converges monotonically to the critical step (from below when stable, from above when not): it
is iterated at the start, at every re-measurement (every BENDING_REFRESH steps) and whenever the largest positive
tension has moved by more than SIGMA_DRIFT since the last one (the reversal, the tension's recovery), until it moves
< 5%; the step is dt_safety times it, capped at ``MAX_GAIN`` times the start's explicit limit. With the tension
in J_s this measured limit replaces the tension formula's (which, on the default job's S = 553 case, allowed steps
1.2x beyond the real limit of the explicit step: benchmarks/bench_tension_stiffness.py).

Cost. P (the cotan matrices, the normals, alpha and beta) is built once per measurement, not every step: the
splitting is consistent for any fixed P, so it may lag the shape. The system's matrix is kept per step length d, and
a matrix for d serves steps from REUSE d to d (a shorter step is stabilised d / dt times more, so never less).

Why this design (and not ves3d's or IBAMR's). ves3d (Rahimian, Veerapaneni, Biros et al.) treats bending and
tension implicitly by solving, each step, the linearised system x - dt S[f_b(x) + f_sigma(ten)] with GMRES: every
Krylov product is a Stokes single-layer evaluation, preconditioned by the spectral diagonal of the sphere. IBAMR's
implicit IB (Griffith; Guy, Philip & Griffith's Stokes-IB preconditioners) is a Newton-Krylov solve of the coupled
fluid-structure system, again a Stokes solve per Krylov iteration. Here the Stokes solve on the 128^3 grid is the
expensive part (issue 48: the products are a third of a step), and the stiff modes sit where the IBM's own mobility
has saturated, so a stabilisation that knows only the mesh and no fluid costs one sparse solve and leaves the
Stokes solves per step unchanged. Its price is first-order accuracy at the wrinkles (dt p(l_*), measured in the
explanation page) and a stability guarantee only where p >= lam / 2, which is why the step stays measured.

Measured (docs/explanation/implicit-stiffness.md): with alpha alone the stabilised limit relaxed 4.06x at 128^3, but
the tension and growth limits bound right behind it (132 -> 123 steps); with beta and the measured rule in place of
the tension formula, the stabilised critical step is 6.6-6.7x the explicit one on stretched frames at S = 553 and
2224. At 32^3 and 64^3 the stiffest mode is the volume penalty's (low l, mostly tangential), which P does not touch.
``NormalStiffness(normal_only=False)`` applies P to
each Cartesian component instead (at 32^3 with the volume penalty it did not relax the limit either).

Limitations: the stabilised normal displacement is not re-projected on the area constraint (the
next step's tension solve holds the area error it leaves, as it does the linearisation's); noise (kT > 0) and the
midpoint scheme are refused (the fluctuation-dissipation balance of the mesh-scale modes would change).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import NumericalInstability
from ..geometry.surface import cross_rows, dot_rows, triangle_areas, vertex_normals
from .integrators import Inextensible

#: the relaxed bending limit may exceed the start's explicit one by at most this factor (modes the Arnoldi start
#: vector misses, and the unconditionally stable case |mu| -> 0, stay bounded)
MAX_GAIN = 16.0
#: the stabilised limit is re-measured (and P rebuilt) when the largest positive tension moves by this fraction
SIGMA_DRIFT = 0.25
#: a factorisation of I + d P serves steps dt from REUSE d to d (a shorter step is stabilised d / dt times more)
REUSE = 0.7
#: relative residual of the stiffness solve (the splitting is consistent for any fixed P; an inexact solve adds an
#: O(SOLVE_RTOL |dX|) perturbation per step)
SOLVE_RTOL = 1e-9


def _cot_and_areas(X, faces):
    """Per-triangle cotangents of the three corner angles (F, 3) and triangle areas (F,)."""
    P = X[faces]  # (F, 3, 3)
    cots = np.empty((faces.shape[0], 3))
    for c in range(3):
        a = P[:, (c + 1) % 3] - P[:, c]
        b = P[:, (c + 2) % 3] - P[:, c]
        cots[:, c] = dot_rows(a, b) / np.linalg.norm(cross_rows(a, b), axis=1)
    return cots, triangle_areas(X, faces)


def cotan_laplacian(X, faces):
    """-> (C, m): the cotan stiffness matrix C (V x V, CSR, symmetric positive semi-definite, C 1 = 0) and the
    vertices' Voronoi areas m (V,), so that -Delta_S f ~ C f / m. Obtuse corners' negative Voronoi shares are kept
    (they sum to the triangle's area); each vertex area is floored at a tenth of its barycentric area."""
    X = np.asarray(X, dtype=np.float64)
    faces = np.asarray(faces)
    V = X.shape[0]
    cots, area = _cot_and_areas(X, faces)
    rows, cols, vals = [], [], []
    m = np.zeros(V)
    for c in range(3):
        i, j = faces[:, (c + 1) % 3], faces[:, (c + 2) % 3]  # the edge opposite corner c
        w = 0.5 * cots[:, c]
        rows += [i, j, i, j]
        cols += [j, i, i, j]
        vals += [-w, -w, w, w]
        e2 = np.sum((X[i] - X[j]) ** 2, axis=1)
        np.add.at(m, i, e2 * cots[:, c] / 8.0)
        np.add.at(m, j, e2 * cots[:, c] / 8.0)
    C = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(V, V))
    bary = np.bincount(faces.ravel(), weights=np.repeat(area / 3.0, 3), minlength=V)
    return C, np.maximum(m, 0.1 * bary)


def stabilisation_alpha(lam_stiff: float, l_c: float) -> float:
    """alpha [R^4 / tau] such that the symbol alpha (l(l+1))^2 equals lam_stiff / 2 at l = l_c."""
    return lam_stiff / (2.0 * (l_c * (l_c + 1.0)) ** 2)


def tension_beta(sigma_max: float, h: float, coupling: str, l_c: float) -> float:
    """beta [R^2 / tau] such that beta l(l+1) equals half the tension formula's rate 2 sigma_max / (c h)
    (integrators.TENSION_STABILITY) at l = l_c; 0 for a tension that is nowhere positive (a compressive tension
    adds no stiffness: measured, docs/explanation/implicit-stiffness.md)."""
    from .integrators import TENSION_STABILITY

    rate = 2.0 * max(float(sigma_max), 0.0) / (TENSION_STABILITY[coupling] * h)
    return rate / (2.0 * l_c * (l_c + 1.0))


class NormalStiffness:
    """P = n [alpha (M^{-1} C)^2 + beta M^{-1} C] n^T at one shape X (module docstring): apply it, or solve
    (I + dt P) dX' = dX. ``normal_only=False``: the same on each Cartesian component instead (it also covers the
    discrete bending force's tangential mesh modes; module docstring, Sizing). P is symmetric positive
    semi-definite in the M inner product for alpha, beta >= 0; the splitting is consistent for any such fixed P, so
    one instance (and its factorisations) serves until the run refreshes it."""

    def __init__(self, X, faces, alpha: float, normal_only: bool = True, beta: float = 0.0):
        if alpha < 0 or beta < 0:
            raise ValueError(f"NormalStiffness needs alpha, beta >= 0, got {alpha}, {beta}")
        self.alpha = float(alpha)
        self.beta = float(beta)
        self.normal_only = normal_only
        self.C, self.m = cotan_laplacian(X, faces)
        self.n = vertex_normals(X, faces)
        self._K = (self.alpha * (self.C @ sp.diags(1.0 / self.m) @ self.C) + self.beta * self.C).tocsc()
        self._A = {}
        self.factorisations = 0  # matrices M + dt K assembled (one per step length d used)

    def scalar(self, s):
        """[alpha (M^{-1} C)^2 + beta M^{-1} C] s for a scalar field s (V,) or (V, k)."""
        m = self.m if np.ndim(s) == 1 else self.m[:, None]
        Ls = (self.C @ s) / m
        return self.alpha * (self.C @ Ls) / m + self.beta * Ls

    def apply(self, dX):
        """P dX (V, 3)."""
        if not self.normal_only:
            return self.scalar(np.asarray(dX, dtype=np.float64))
        s = dot_rows(self.n, dX)
        return self.n * self.scalar(s)[:, None]

    def matrix(self, dt: float):
        """M + dt M P (CSR), symmetric positive definite: (I + dt P) s' = s is M s' + dt K s' = M s."""
        A = self._A.get(dt)
        if A is None:
            if len(self._A) >= 8:  # the fixed point's trial steps: keep the last few
                self._A.pop(next(iter(self._A)))
            A = (sp.diags(self.m) + dt * self._K).tocsr()
            self._A[dt] = A, sp.diags(1.0 / A.diagonal())
            self.factorisations += 1
            A = self._A[dt]
        return A

    def solve(self, dt: float, dX, rtol: float = SOLVE_RTOL):
        """(I + dt P)^{-1} dX (V, 3); with normal_only, only the normal component changes. Conjugate gradients
        with the diagonal as preconditioner, from dX itself (P is small on the smooth part that carries dX's
        norm): 20-60 iterations, 20-50 ms at 9512 vertices, where SuperLU's factorisation of this two-ring matrix
        took 2.6-5.3 s (measured; docs/explanation/implicit-stiffness.md)."""
        A, Dinv = self.matrix(dt)
        dX = np.asarray(dX, dtype=np.float64)
        if not self.normal_only:
            return np.stack([self._cg(A, Dinv, dX[:, k]) for k in range(dX.shape[1])], axis=1)
        s = dot_rows(self.n, dX)
        s_new = self._cg(A, Dinv, s, rtol)
        return dX + self.n * (s_new - s)[:, None]

    def _cg(self, A, Dinv, s, rtol=SOLVE_RTOL):
        out, info = spla.cg(A, self.m * s, x0=s, M=Dinv, rtol=rtol, atol=0.0, maxiter=2000)
        if info != 0:
            raise NumericalInstability(f"stiffness solve (I + dt P) s' = s did not converge in {info} iterations")
        return out


def critical_step(P: NormalStiffness, J, v, d: float, cap: float, xp=np, be=None, iters: int = 6):
    """The stabilised step's stability limit: the fixed point d <- 2 / |mu|max((I + d P)^{-1} J) from d (module
    docstring, Step size) -> (d, |mu|max, its mode, products, fixed-point iterations). J: v -> J v (one Stokes
    solve); v: the Arnoldi start vector; d is capped at ``cap``."""
    from .step_size import arnoldi

    host = (lambda a: a) if be is None else be.asnumpy
    products = it = 0
    mu = 0.0
    while it < iters:
        it += 1
        def apply(w, d=d):
            return xp.asarray(P.solve(d, host(J(w))))

        mu, v, n = arnoldi(apply, xp.asarray(v) + 0.0, max_iter=20, rtol=1e-3, min_iter=3)
        products += n
        d_new = min(2.0 / mu, cap) if mu > 0 else cap
        converged = abs(d_new - d) < 0.05 * d
        d = d_new
        if converged:
            break
    return d, mu, v, products, it


def tension_operator(X, faces, cfg, lam_bending: float, sigma_max: float, normal_only: bool = True):
    """The run's P at the shape X: alpha from the explicit bending rate lam_bending, beta from the tension's largest
    positive value, both reaching half their rates at l_c (``stiffness_l``, default half the grid's l)."""
    l_c = float(cfg.stiffness_l) if cfg.stiffness_l is not None else 0.5 * math.ceil(math.pi / cfg.h)
    beta = tension_beta(sigma_max, cfg.h, cfg.coupling, l_c) if cfg.stiffness_tension else 0.0
    return NormalStiffness(X, faces, stabilisation_alpha(lam_bending, l_c), normal_only=normal_only, beta=beta)


class StabilisedInextensible(Inextensible):
    """The inextensible scheme with the mesh-scale stiffness stabilised implicitly along the normals (module
    docstring): (I + d P) dX = dt U, P = n [alpha (-L)^2 + beta (-L)] n^T. The bending limit is the measured
    stability limit of this step with the tension frozen (J_s), which replaces the tension formula's limit. P and
    its factorisation are kept from one refresh to the next (module docstring, Cost)."""

    normal_only = True  # P on the normal component (False: on each Cartesian component)

    def __init__(self, solver, dt_bending: float, X0=None):
        super().__init__(solver, dt_bending, X0)
        cfg = self.cfg
        self.dt_explicit = dt_bending  # the start's explicit limit, 2 / lam_0
        self.lam_0 = 2.0 / dt_bending
        self.l_c = float(cfg.stiffness_l) if cfg.stiffness_l is not None else 0.5 * self.l_grid
        self.alpha = stabilisation_alpha(self.lam_0, self.l_c)
        self._faces = np.asarray(solver.be.asnumpy(solver.membrane.topo.faces))
        self._relaxed = None  # the measured critical step of the stabilised scheme (tau)
        self.relaxations = 0  # the fixed-point iterations spent (each one Arnoldi measurement)
        self.P = None  # the operator in use, built at the last measurement
        self._d = None  # the step its factorisation in use is for
        self._sigma_sized = 0.0  # the largest tension P's beta and the measurement were made at
        self.refreshes = 0
        self.factorisations = 0
        self.beta_max = 0.0

    def _sigma_max(self, state) -> float:
        if state.sigma is None:
            return 0.0
        return max(float(np.max(self.solver.be.asnumpy(state.sigma))), 0.0)

    def _stale(self, state) -> bool:
        """The measurement no longer stands for the step: none yet, or the largest tension moved by more than
        SIGMA_DRIFT of the one it was made at (floored at a tension whose formula rate is a tenth of the bending
        rate: below that the tension's stiffness is within the measurement's margin)."""
        from .integrators import TENSION_STABILITY

        if self._relaxed is None:
            return True
        floor = 0.1 * self.lam_0 * TENSION_STABILITY[self.cfg.coupling] * self.cfg.h / 2.0
        return abs(self._sigma_max(state) - self._sigma_sized) > SIGMA_DRIFT * max(self._sigma_sized, floor)

    def bending_limit(self, state) -> float:
        return self._relaxed if self._relaxed is not None else self.dt_bending

    def next_dt(self, state, geo) -> float:
        if state.step != self._bending_step and self._stale(state):
            self._measure_bending(state)
        dt = super().next_dt(state, geo)
        if "tension" in self.limits and self.cfg.stiffness_tension:
            # the measured limit includes the tension's frozen stiffness, so the formula's stands down
            limits = {k: v for k, v in self.limits.items() if k != "tension"}
            self.limits, self.binding_limit = limits, min(limits, key=limits.get)
            dt = limits[self.binding_limit]
        return dt

    def _build(self, X, state) -> None:
        if self.P is not None:
            self.factorisations += self.P.factorisations
        smax = self._sigma_max(state)
        self.P = tension_operator(np.asarray(self.solver.be.asnumpy(X), dtype=np.float64), self._faces, self.cfg,
                                  self.lam_0, smax, normal_only=self.normal_only)
        self._sigma_sized, self._d = smax, None
        self.beta_max = max(self.beta_max, self.P.beta)
        self.refreshes += 1

    def _measure_bending(self, state) -> None:
        """Rebuild P at the current shape and tension, then the fixed point d <- 2 / |mu|max((I + d P)^{-1} J_s)
        (module docstring, Step size)."""
        from .step_size import stiffness_product

        xp = self.solver.xp
        self._build(state.X, state)
        sigma = state.sigma if self.cfg.stiffness_tension else None
        J = stiffness_product(self.solver, state.X, sigma)
        v = state.bending_mode
        if v is None:
            v = xp.asarray(np.random.default_rng(state.step).standard_normal(state.X.shape))
        d, _, v, products, it = critical_step(self.P, J, v, self.bending_limit(state), MAX_GAIN * self.dt_explicit,
                                              xp, self.solver.be)
        self.bending_solves += products
        self.relaxations += it
        self._bending_step = state.step
        self._relaxed = state.dt_bending = d
        state.bending_mode = v
        self.dt_bending_min = min(self.dt_bending_min, d)
        self.dt_bending_last = d

    def finish_step(self, state, X, geo, sigma, U, dt, ref, strain):
        if self.P is None:  # a step without next_dt (tests): P at this shape and tension
            self._build(X, state)
        if self._d is None or not (REUSE * self._d <= dt <= self._d):
            # a factorisation for a longer step stabilises a shorter one more (p d / dt): reused down to REUSE
            self._d = dt
        U = self.solver.xp.asarray(self.P.solve(self._d, self.solver.be.asnumpy(U)), dtype=U.dtype)
        strain = self.linearisation_strain(X, U * dt) if self.thermal is None else 0.0
        return super().finish_step(state, X, geo, sigma, U, dt, ref, strain)

    def stats(self) -> dict:
        out = super().stats()
        out.update(stiffness_alpha=self.alpha, stiffness_beta_max=self.beta_max, stiffness_l_used=self.l_c,
                   stiffness_relaxations=self.relaxations, stiffness_refreshes=self.refreshes,
                   stiffness_matrices=self.factorisations + (self.P.factorisations if self.P else 0),
                   dt_explicit_start_tau=float(self.dt_explicit))
        return out


def symbol(l, alpha: float = 1.0, R: float = 1.0, beta: float = 0.0):
    """The continuum symbol of alpha (-Delta_S)^2 + beta (-Delta_S) on a sphere of radius R for Y_lm:
    alpha (l(l+1))^2 / R^4 + beta l(l+1) / R^2."""
    l = np.asarray(l, dtype=float)
    ll = l * (l + 1.0)
    return alpha * ll**2 / R**4 + beta * ll / R**2


__all__ = ["MAX_GAIN", "NormalStiffness", "StabilisedInextensible", "cotan_laplacian", "critical_step",
           "stabilisation_alpha", "symbol", "tension_beta", "tension_operator"]
