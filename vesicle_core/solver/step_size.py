"""The time step of an IBM run: the stability estimates and the base step of a fresh run.

Time step. Explicit stepping is limited by the stiffest membrane mode: the area penalty
(dt ~ 40 h / Lambda) or bending (dt ~ 13 h^3), both measured by an Arnoldi iteration. ``dt_rule="power"`` (default;
the name is kept from the power iteration this replaced) measures the largest eigenvalue |lam| of the linearised
velocity operator dX/dt = M F(X) at the initial shape and takes dt = safety * 2 / |lam| (explicit Euler is stable for
|lam| dt < 2 on the real negative spectrum), capped by the formula estimate and by 0.01 / chi so the
flow is resolved; ``dt_rule="formula"`` uses the formula only; a number fixes dt (in tau).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ..model.run_config import RunConfig
from ..xp import array_module, to_float
from .membrane import volume, volume_gradient
from .mobility import IBMSolver
from .tension import face_DT

__all__ = ["arnoldi", "formula_dt", "initial_dt", "stability_dt", "stiffest_mode", "stiffness_product"]

log = logging.getLogger("vesicle_core.solver.simulate")  # the estimates are part of the run's log


def formula_dt(cfg: RunConfig, edge_mean: float, flow: bool = True) -> float:
    """Stable-step estimate (tau) measured on the linearised operator (eigenvalue iteration): area penalty
    40 h/Lambda, bending 13 h^3 (edge ~ h) to 20 h^3 (edge ~ 2h), and 0.01/chi so the background flow moves a
    vertex by < 1% of R per step."""
    h = cfg.h
    lam = (0.0 if cfg.scheme == "inextensible" else cfg.Lambda_eff) + cfg.K_area
    c_b = 13.0 + 7.0 * min(max(edge_mean / h - 1.0, 0.0), 1.0)
    limits = [c_b * h**3]
    if lam > 0:
        limits.append(40.0 * h / lam)
    if cfg.chi > 0 and flow:
        limits.append(0.01 / cfg.chi)
    return min(limits)


def stability_dt(solver: IBMSolver, X, max_iter=40, seed=0) -> tuple[float, float]:
    """Largest |eigenvalue| of the linearised membrane velocity at X, from a random start -> (2/|lam|, |lam|)."""
    lam, _, _ = stiffest_mode(solver, X, max_iter=max_iter, seed=seed)
    return (2.0 / lam if lam > 0 else math.inf), lam


def stiffest_mode(solver: IBMSolver, X, v0=None, max_iter=40, rtol=1e-3, seed=0, min_iter=3):
    """The stiffest mode of the linearised membrane velocity dX/dt = M(X) F(X) at X -> (|lam|, unit vector, solves).

    Arnoldi iteration on J v = M(X) dF/dX v: the force's derivative a centred finite difference (forces only, in
    float64) and one Stokes solve per iteration. A difference of the velocity instead, as the power iteration did,
    is swamped by the grid's float32 rounding at a step of 1e-7 R: on a frame of a 128^3 run, Arnoldi on it returned
    2.36e4-2.64e4 /tau from three random starts, with residuals 1.2-3.4x the value, against 2.370e4 (residual 1e-3)
    in float64; this force difference gives 2.373e4. Two terms of the whole linearisation are left out, by design:
    the mobility's change along v times the force, (dM/dX v) F, of the order of |F| over the kernel width, while the
    stiff modes have |dF/dX| ~ kappa / h^4; and the volume penalty's pressure p = K (V - V0) / V0 times the volume's
    Hessian, p Hess(V) v, which is added back: a uniform pressure drives no flow at any shape (M grad V = 0 for
    incompressible Stokes), so in the whole linearisation it cancels against (dM/dX v) p grad V. Returns the Ritz
    value of largest modulus once it changes by less than ``rtol`` in two iterations running (at least ``min_iter``
    iterations, at most ``max_iter`` solves).

    Why not power iteration (what it replaced): the stiff end of the spectrum is a cluster of mesh-scale modes, so a
    power iteration converges slowly, and on the float32 grid its velocity differences are noisy. On six frames of a
    128^3 run of the default discretisation it came 4-9% below the float64 reference when warm (rtol 1e-2, 4-34
    solves) and -9% to +10% from it when cold (20-60 solves); Arnoldi came within 0.5% in 3-12 solves warm (3.5%
    across a 180-step gap) and 19-23 cold (benchmarks/bench_step_size.py; docs/history/solver.md, "The bending limit's
    measurement").

    ``v0``: a start vector (the last measurement's, so that a re-measurement on a slowly changing shape needs a
    few iterations); None: a random one from ``seed``.
    """
    xp = solver.xp
    v = xp.asarray(np.random.default_rng(seed).standard_normal(X.shape)) if v0 is None else xp.asarray(v0) + 0.0
    return arnoldi(stiffness_product(solver, X), v, max_iter=max_iter, rtol=rtol, min_iter=min_iter)


def arnoldi(apply, v, max_iter=40, rtol=1e-3, min_iter=3):
    """Largest |eigenvalue| of the linear map ``apply`` by Arnoldi iteration from the vector v (any shape, NumPy or
    CuPy) -> (|lam|, its unit Ritz vector (real part), products). Stops once the largest Ritz value changes by less
    than ``rtol`` in two iterations running, after at least ``min_iter``."""
    xp = array_module(v)
    basis = [v / to_float(xp.linalg.norm(v))]
    H = np.zeros((max_iter + 1, max_iter))
    lam, coef, calm, j = 0.0, np.ones(1), 0, 0
    for j in range(max_iter):
        u = apply(basis[j])
        for _ in range(2):  # Gram-Schmidt twice: the basis stays orthogonal to rounding
            for i in range(j + 1):
                hij = to_float(xp.vdot(basis[i], u))
                H[i, j] += hij
                u = u - hij * basis[i]
        H[j + 1, j] = to_float(xp.linalg.norm(u))
        ritz, vecs = np.linalg.eig(H[: j + 1, : j + 1])
        k = int(np.argmax(np.abs(ritz)))
        new = float(abs(ritz[k]))
        coef = vecs[:, k].real
        calm = calm + 1 if abs(new - lam) < rtol * new else 0
        lam = new
        if (j + 1 >= min_iter and calm >= 2) or H[j + 1, j] <= 1e-12 * new:
            break
        basis.append(u / H[j + 1, j])
    vec = sum(float(c) * b for c, b in zip(coef, basis, strict=False))  # the Ritz vector, built once at the end
    return lam, vec / to_float(xp.linalg.norm(vec)), j + 1


def stiffness_product(solver: IBMSolver, X, sigma=None):
    """v -> M(X) dF/dX v (float64) at the shape X, as stiffest_mode uses it: the force's derivative a centred
    difference in float64, the volume penalty's p Hess(V) v added back, one Stokes solve per product.

    ``sigma`` (F,): a per-triangle tension held frozen (the inextensible scheme's, solved at X), whose force
    -D(X)^T sigma is differenced with the rest: its derivative -sum_t sigma_t Hess(A_t) v is the tension's
    linearised stiffness at fixed sigma, the part of the step the tension limit (integrators.TENSION_STABILITY)
    stands for. The tension's own response to v (the constraint's re-solve) is left out."""
    xp = solver.xp
    scale = 1e-7 * to_float(xp.abs(X).max())
    mem = solver.membrane
    pressure = mem.K_volume * (volume(X, mem.topo) - mem.ref.volume) / mem.ref.volume
    frozen = None if sigma is None else xp.asarray(sigma, dtype=xp.float64)
    # the forces are spread at X itself, not at the displaced shapes: one stencil for every product, valid until
    # the coupler is prepared at other points (the integrator's step does that after each measurement)
    solver.coupler.prepare(X)

    def apply(v):
        w = scale * v
        (Fp, gp), (Fm, gm) = solver.forces(X + w), solver.forces(X - w)
        dF = Fp - Fm
        if frozen is not None:
            dF -= face_DT(frozen, gp, mem.topo) - face_DT(frozen, gm, mem.topo)
        if pressure:
            dF += pressure * (volume_gradient(X + w, mem.topo) - volume_gradient(X - w, mem.topo))
        dF /= 2 * scale
        return xp.asarray(solver.induced_displacement(X, dF, 1.0, advance=False, same_points=True), dtype=xp.float64)

    return apply


def initial_dt(cfg: RunConfig, solver: IBMSolver, X, edge_mean: float) -> float:
    """The base step (tau) of a fresh run: fixed, or from the stability estimates at the initial shape X."""
    dt_f = formula_dt(cfg, edge_mean)
    if isinstance(cfg.dt, str) and cfg.scheme == "inextensible":
        # the stability limit of the bending force; the integrator adds tension, growth and flow limits
        dt = 2.0 * formula_dt(cfg, edge_mean, flow=False)
        if cfg.dt == "power":
            dt_p, lam = stability_dt(solver, X)
            log.info("Arnoldi iteration (bending): |lam|max = %.4g /tau -> dt_crit = %.4g tau", lam, dt_p)
            dt = min(dt_p, dt)
        return dt
    if isinstance(cfg.dt, str):
        if cfg.dt == "power":
            dt_p, lam = stability_dt(solver, X)
            dt = cfg.dt_safety * min(dt_p, 2.0 * dt_f)
            log.info("Arnoldi iteration: |lam|max = %.4g /tau -> dt_crit = %.4g tau (formula %.4g)", lam, dt_p, dt_f)
        else:
            dt = cfg.dt_safety * dt_f
        if cfg.chi > 0:
            dt = min(dt, 0.01 / cfg.chi)
        return dt
    return float(cfg.dt)
