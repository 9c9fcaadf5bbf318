r"""The mesh-scale bending stiffness taken off the step: a linearly stabilised inextensible scheme (run parameter
``stiffness: implicit``; a prototype, not the default).

Operator. On the vertex normals n_k, with C the cotan Laplacian's stiffness matrix
(C_ij = -(cot a_ij + cot b_ij) / 2 on an edge, C_ii = -sum_j C_ij) and M the vertices' Voronoi areas,
-Delta_S ~ M^{-1} C, and

    P dX = n alpha (M^{-1} C)^2 (n . dX)        (tangential components untouched)

On a sphere of radius R a normal displacement s Y_lm is an eigenfunction of -Delta_S with eigenvalue l(l+1) / R^2,
so the continuum symbol of P is alpha (l(l+1))^2 / R^4 (``tests/solver/test_implicit_stiffness.py`` checks the
discrete operator against it on an icosphere). The bending force of the Helfrich energy linearised about a sphere
has the symbol kappa l(l+1)(l-1)(l+2) / R^4 (eq. 11's Gamma_l before the mobility), the same (-Delta)^2 at large l:
P has the shape of the stiff part of the force, without its mobility.

Splitting (linearly stabilised forward Euler; the small-scale decomposition's idea, Hou, Lowengrub & Shelley, J.
Comput. Phys. 114 (1994) 312, and for the immersed boundary Hou & Shi, J. Comput. Phys. 227 (2008) 8968): with U(X)
the inextensible scheme's velocity (tension solved, flow and background included),

    (X^{n+1} - X^n) / dt = U(X^n) - P (X^{n+1} - X^n)   <=>   (I + dt P) dX = dt U(X^n)

P is added implicitly and, through dX ~ dt U, subtracted explicitly to O(dt): the step stays first order and
consistent, and a mode of rate -lam (lam > 0) and symbol p amplifies by g = 1 - dt lam / (1 + dt p). It is stable for
dt (lam - 2 p) <= 2: where p >= lam / 2 (the stiff mesh-scale modes, once alpha is sized for them) for every dt.
A wrinkle's growth rate r becomes r / (1 + dt p(l)): the splitting's error there is dt p(l), which is why P must be
small at the wrinkles' l. Only the normal part is solved for: (I + dt alpha (M^{-1} C)^2) s' = s, multiplied by M
into the symmetric positive definite (M + dt alpha C M^{-1} C) s' = M s, one sparse factorisation (SuperLU) per step,
no Stokes solve.

Sizing. alpha = lam_0 / (2 (l_c (l_c + 1))^2), lam_0 the start's explicit stiffest rate (step_size.stiffest_mode):
the stabilisation reaches half the stiffest rate at l_c (``stiffness_l``, default half the grid's l, ceil(pi R / h)
/ 2), so every mode from l_c up, where the rate has saturated at lam_0 (docs/history/solver.md: the stiff modes are
l ~ 40-96 at 128^3), is stable at any dt. Below l_c, P falls as l^4 while the rate falls as ~l^3, so a residue of
explicit stiffness remains, and the step-size rule measures it rather than assuming it:

Step size. The bending limit is the stability limit of the step actually taken. For a step length d, the Arnoldi
iteration of step_size runs on K_d = (I + d P)^{-1} J (J = M dF/dX, the explicit scheme's linearisation, one Stokes
solve and one sparse solve per product); the step is stable while d |mu|max(K_d) <= 2. d |mu|max(K_d) increases with
d, so d <- 2 / |mu|max(K_d) converges monotonically to the critical step (from below when stable, from above when
not): it is iterated at the start and at every re-measurement (every BENDING_REFRESH steps) until it moves < 5%, and
the step is dt_safety times it, as with the explicit limit, capped at ``MAX_GAIN`` times the start's explicit limit.

Why this design (and not ves3d's or IBAMR's). ves3d (Rahimian, Veerapaneni, Biros et al.) treats bending and
tension implicitly by solving, each step, the linearised system x - dt S[f_b(x) + f_sigma(ten)] with GMRES: every
Krylov product is a Stokes single-layer evaluation, preconditioned by the spectral diagonal of the sphere. IBAMR's
implicit IB (Griffith; Guy, Philip & Griffith's Stokes-IB preconditioners) is a Newton-Krylov solve of the coupled
fluid-structure system, again a Stokes solve per Krylov iteration. Here the Stokes solve on the 128^3 grid is the
expensive part (issue 48: the products are a third of a step), and the stiff modes sit where the IBM's own mobility
has saturated, so a stabilisation that knows only the mesh and no fluid costs one sparse factorisation and leaves the
Stokes solves per step unchanged. Its price is first-order accuracy at the wrinkles (dt p(l_*), measured in the
explanation page) and a stability guarantee only where p >= lam / 2, which is why the step stays measured.

Measured (docs/explanation/implicit-stiffness.md): at 128^3 the stabilised limit relaxed 4.06x, but the tension
and growth limits bind right behind it (132 -> 123 steps); at 32^3 and 64^3 the stiffest mode is the volume
penalty's (low l, mostly tangential), which P does not touch. ``NormalStiffness(normal_only=False)`` applies P to
each Cartesian component instead (at 32^3 with the volume penalty it did not relax the limit either).

Limitations of this prototype: the stabilised normal displacement is not re-projected on the area constraint (the
next step's tension solve holds the area error it leaves, as it does the linearisation's); noise (kT > 0) and the
midpoint scheme are refused (the fluctuation-dissipation balance of the mesh-scale modes would change).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..geometry.surface import cross_rows, dot_rows, triangle_areas, vertex_normals
from .integrators import Inextensible

#: the relaxed bending limit may exceed the start's explicit one by at most this factor (modes the Arnoldi start
#: vector misses, and the unconditionally stable case |mu| -> 0, stay bounded)
MAX_GAIN = 16.0


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


class NormalStiffness:
    """P = n alpha (M^{-1} C)^2 n^T at one shape X (module docstring): apply it, or solve (I + dt P) dX' = dX.
    ``normal_only=False``: alpha (M^{-1} C)^2 on each Cartesian component instead (it also covers the discrete
    bending force's tangential mesh modes; module docstring, Sizing)."""

    def __init__(self, X, faces, alpha: float, normal_only: bool = True):
        self.alpha = float(alpha)
        self.normal_only = normal_only
        self.C, self.m = cotan_laplacian(X, faces)
        self.n = vertex_normals(X, faces)
        self._CMC = (self.C @ sp.diags(1.0 / self.m) @ self.C).tocsc()
        self._lu = {}

    def scalar(self, s):
        """alpha (M^{-1} C)^2 s for a scalar field s (V,) or (V, k)."""
        m = self.m if np.ndim(s) == 1 else self.m[:, None]
        return self.alpha * (self.C @ ((self.C @ s) / m)) / m

    def apply(self, dX):
        """P dX (V, 3)."""
        if not self.normal_only:
            return self.scalar(np.asarray(dX, dtype=np.float64))
        s = dot_rows(self.n, dX)
        return self.n * self.scalar(s)[:, None]

    def solve(self, dt: float, dX):
        """(I + dt P)^{-1} dX (V, 3); with normal_only, only the normal component changes."""
        lu = self._lu.get(dt)
        if lu is None:
            A = (sp.diags(self.m) + (dt * self.alpha) * self._CMC).tocsc()
            lu = self._lu[dt] = spla.splu(A)
        dX = np.asarray(dX, dtype=np.float64)
        if not self.normal_only:
            return lu.solve(self.m[:, None] * dX)
        s = dot_rows(self.n, dX)
        s_new = lu.solve(self.m * s)
        return dX + self.n * (s_new - s)[:, None]


class StabilisedInextensible(Inextensible):
    """The inextensible scheme with the mesh-scale stiffness stabilised implicitly along the normals (module
    docstring): (I + dt P) dX = dt U. The bending limit is the measured stability limit of this step."""

    normal_only = True  # P on the normal component (False: on each Cartesian component)

    def __init__(self, solver, dt_bending: float, X0=None):
        super().__init__(solver, dt_bending, X0)
        cfg = self.cfg
        self.dt_explicit = dt_bending  # the start's explicit limit, 2 / lam_0
        self.l_c = float(cfg.stiffness_l) if cfg.stiffness_l is not None else 0.5 * self.l_grid
        self.alpha = stabilisation_alpha(2.0 / dt_bending, self.l_c)
        self._faces = np.asarray(solver.be.asnumpy(solver.membrane.topo.faces))
        self._relaxed = None  # the measured critical step of the stabilised scheme (tau)
        self.relaxations = 0  # the fixed-point iterations spent (each one Arnoldi measurement)

    def _operator(self, X):
        return NormalStiffness(np.asarray(self.solver.be.asnumpy(X), dtype=np.float64), self._faces, self.alpha,
                               normal_only=self.normal_only)

    def bending_limit(self, state) -> float:
        return self._relaxed if self._relaxed is not None else self.dt_bending

    def next_dt(self, state, geo) -> float:
        if self._relaxed is None and state.step != self._bending_step:
            self._measure_bending(state)
        return super().next_dt(state, geo)

    def _measure_bending(self, state) -> None:
        """Fixed point d <- 2 / |mu|max((I + d P)^{-1} J) at the current shape (module docstring, Step size)."""
        from .step_size import arnoldi, stiffness_product

        xp = self.solver.xp
        J = stiffness_product(self.solver, state.X)
        P = self._operator(state.X)
        d = self.bending_limit(state)
        v = state.bending_mode
        if v is None:
            v = xp.asarray(np.random.default_rng(state.step).standard_normal(state.X.shape))
        cap = MAX_GAIN * self.dt_explicit
        for _ in range(6):
            def apply(w, d=d):
                return xp.asarray(P.solve(d, self.solver.be.asnumpy(J(w))))

            mu, v, solves = arnoldi(apply, xp.asarray(v) + 0.0, max_iter=20, rtol=1e-3, min_iter=3)
            self.bending_solves += solves
            self.relaxations += 1
            d_new = min(2.0 / mu, cap) if mu > 0 else cap
            converged = abs(d_new - d) < 0.05 * d
            d = d_new
            if converged:
                break
        self._bending_step = state.step
        self._relaxed = state.dt_bending = d
        state.bending_mode = v
        self.dt_bending_min = min(self.dt_bending_min, d)
        self.dt_bending_last = d

    def finish_step(self, state, X, geo, sigma, U, dt, ref, strain):
        U = self.solver.xp.asarray(self._operator(X).solve(dt, self.solver.be.asnumpy(U)), dtype=U.dtype)
        strain = self.linearisation_strain(X, U * dt) if self.thermal is None else 0.0
        return super().finish_step(state, X, geo, sigma, U, dt, ref, strain)

    def stats(self) -> dict:
        out = super().stats()
        out.update(stiffness_alpha=self.alpha, stiffness_l_used=self.l_c, stiffness_relaxations=self.relaxations,
                   dt_explicit_start_tau=float(self.dt_explicit))
        return out


def symbol(l, alpha: float = 1.0, R: float = 1.0):
    """The continuum symbol of alpha (-Delta_S)^2 on a sphere of radius R for Y_lm: alpha (l(l+1))^2 / R^4."""
    l = np.asarray(l, dtype=float)
    return alpha * (l * (l + 1.0)) ** 2 / R**4


__all__ = ["MAX_GAIN", "NormalStiffness", "StabilisedInextensible", "cotan_laplacian", "stabilisation_alpha",
           "symbol"]
