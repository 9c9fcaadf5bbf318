"""A tension preconditioner learned from the CG's own products: BFGS updates of the harmonic space's rate operator.

The harmonic tension solve (:mod:`vesicle_core.solver.tension_harmonic`) is CG on

    A(dt) c = (dt R + G / Lambda) c,     R = B^T D M D^T B  (K x K, K = (l_t + 1)^2),

preconditioned by the quasi-sphere's diagonal in l, rho_l. That diagonal is what the warm deterministic step needs
(1 iteration, median): its residual is smooth and predicted by the last two steps. A thermal step's is not: the
noise velocity's area rate is new every step and white in the space, so every eigenvalue cluster of the
preconditioned operator shows up in the residual, and CG needed 4.3 iterations per step instead of 1.0 at 64^3
(docs/history/thermal.md, section 8). The operator is small and dense, though, and every CG iteration already computes
one exact product R p (one Stokes solve). Those products are fed into a quasi-Newton model of R:

    R_hat <- R_hat + y y^T / (y . p) - (R_hat p)(R_hat p)^T / (p . R_hat p),      y = R p,

the BFGS update, which makes R_hat p = y exactly and keeps R_hat symmetric positive definite whenever y . p > 0
(R is positive semi-definite; a pair with y . p <= ``min_curvature`` |y| |p| is skipped). CG directions of one solve
are A-conjugate, for which BFGS builds the exact operator on their span (the classical equivalence of BFGS with exact
line searches and CG on a quadratic). Noise directions are random, so after O(K) products R_hat is close to R on the
whole space and the preconditioner (dt R_hat + G / Lambda)^-1 (a K x K Cholesky, refactorised when R_hat or dt
changed) nearly inverts A. The start is the diagonal's own operator, S G S with S = diag(rho_l^(1/2)). No Stokes
solve is spent on it: it only reuses products. Its own cost grows as K^3 (a factorisation per solve, dt changing
every step): ~4 ms per step at K = 400 (2379 vertices), 23 ms per factorisation at K = 441 and 131 ms at K = 1681
(10242 vertices, l_t = 40) on a loaded core, there about one Stokes solve at 128^3. Prior art: limited-memory and
full quasi-Newton preconditioners built from CG's own (p, A p) pairs for sequences of slowly varying systems
(Morales & Nocedal, SIAM J. Optim. 10 (2000); Gratton, Sartenaer & Tshimanga, SIAM J. Optim. 21 (2011)).
"""

from __future__ import annotations

import numpy as np


class SecantPreconditioner:
    """(dt R_hat + G / Lambda)^-1 on the free coefficients, R_hat a BFGS model of R (module docstring).

    G: the space's mass matrix (K, K); free: boolean mask of the solved coefficients (the rest get 0).
    """

    def __init__(self, G, Lambda, free, min_curvature=1e-8, floor=1e-3):
        self.G = np.asarray(G, dtype=float)
        self.Lambda = float(Lambda)
        self.free = np.asarray(free, dtype=bool)
        self.min_curvature = float(min_curvature)
        self.floor = float(floor)  # rho_l below floor x max rho is raised to it in the start model (l = 0 on a sphere)
        self.R = None
        self._pairs = []
        self._chol = None
        self._dt = None
        self.updates = 0
        self.skipped = 0
        self.factorisations = 0

    def start(self, rho, l):
        """The start model S G S, S = diag(sqrt(rho_l)) per coefficient (rho_l floored); pending pairs are dropped."""
        rho = np.asarray(rho, dtype=float)
        s = np.sqrt(np.maximum(rho, self.floor * max(float(rho.max()), 1e-300)))[np.asarray(l)]
        self.R = s[:, None] * self.G * s[None, :]
        self._pairs.clear()
        self._chol = None

    def record(self, p, y):
        """Keep one exact product y = R p (applied at the next ``update``: a solve keeps one preconditioner)."""
        self._pairs.append((np.array(p, dtype=float), np.array(y, dtype=float)))

    def update(self):
        """Apply the recorded pairs, in order, as BFGS updates."""
        if self.R is None:
            self._pairs.clear()
            return
        for p, y in self._pairs:
            yp = float(y @ p)
            Rp = self.R @ p
            pRp = float(p @ Rp)
            if not (yp > self.min_curvature * np.linalg.norm(y) * np.linalg.norm(p) and pRp > 0):
                self.skipped += 1
                continue
            self.R += np.outer(y, y) / yp
            self.R -= np.outer(Rp, Rp) / pRp
            self.updates += 1
            self._chol = None
        if self._pairs:  # the rank-2 terms' round-off, once per solve (K^2 per pair otherwise: 55 ms at K = 1681)
            self.R += self.R.T
            self.R *= 0.5
        self._pairs.clear()

    @property
    def ready(self) -> bool:
        return self.R is not None

    def __call__(self, r, dt):
        """z = (dt R_hat + G / Lambda)^-1 r on the free coefficients, 0 on the others."""
        import scipy.linalg as sl

        if self._chol is None or dt != self._dt:  # a function of (R_hat, dt) only, so a resumed run gets the same
            f = self.free
            A = dt * self.R[np.ix_(f, f)] + self.G[np.ix_(f, f)] / self.Lambda
            self._chol = sl.cho_factor(A, lower=True)
            self._dt = dt
            self.factorisations += 1
        z = np.zeros_like(np.asarray(r, dtype=float))
        z[self.free] = sl.cho_solve(self._chol, np.asarray(r, dtype=float)[self.free])
        return z
