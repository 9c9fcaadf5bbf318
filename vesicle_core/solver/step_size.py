"""The time step of an IBM run: the stability estimates and the base step of a fresh run.

Time step. Explicit stepping is limited by the stiffest membrane mode: the area penalty
(dt ~ 40 h / Lambda) or bending (dt ~ 13 h^3), both measured by power iteration. ``dt_rule="power"`` (default)
measures the largest eigenvalue |lam| of the linearised velocity operator dX/dt = M F(X) by power
iteration at the initial shape and takes dt = safety * 2 / |lam| (explicit Euler is stable for
|lam| dt < 2 on the real negative spectrum), capped by the formula estimate and by 0.01 / chi so the
flow is resolved; ``dt_rule="formula"`` uses the formula only; a number fixes dt (in tau).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ..model.run_config import RunConfig
from .mobility import IBMSolver

__all__ = ["formula_dt", "initial_dt", "power_dt", "power_iteration"]

log = logging.getLogger("vesicle_core.solver.simulate")  # the estimates are part of the run's log


def formula_dt(cfg: RunConfig, edge_mean: float, flow: bool = True) -> float:
    """Stable-step estimate (tau) measured by power iteration on the linearised operator: area penalty
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


def power_dt(solver: IBMSolver, X, iters=30, seed=0) -> tuple[float, float]:
    """Largest |eigenvalue| of the linearised membrane velocity at X by power iteration -> (2/|lam|, |lam|).

    The Jacobian-vector product is a centred finite difference of the velocity (two solves).
    """
    lam, _, _ = power_iteration(solver, X, iters=iters, seed=seed)
    return (2.0 / lam if lam > 0 else math.inf), lam


def power_iteration(solver: IBMSolver, X, v0=None, iters=30, rtol=1e-3, seed=0):
    """Power iteration on the linearised membrane velocity at X -> (|lam|, unit vector, Stokes solves).

    ``v0``: a start vector (the last measurement's, so that a re-measurement on a slowly changing shape needs a few
    iterations); None: a random one from ``seed``. Stops when |lam| changes by less than ``rtol``."""
    xp = solver.xp
    v = xp.asarray(np.random.default_rng(seed).standard_normal(X.shape)) if v0 is None else xp.asarray(v0) + 0.0
    v /= float(xp.linalg.norm(v))
    scale = 1e-7 * float(xp.abs(X).max())
    lam = 0.0
    solves = 0
    for _ in range(iters):
        Jv = (solver.membrane_velocity(X + scale * v) - solver.membrane_velocity(X - scale * v)) / (2 * scale)
        solves += 2
        new = float(xp.linalg.norm(Jv))
        if new == 0 or not math.isfinite(new):
            break
        v = Jv / new
        if abs(new - lam) < rtol * new:
            lam = new
            break
        lam = new
    return lam, v, solves


def initial_dt(cfg: RunConfig, solver: IBMSolver, X, edge_mean: float) -> float:
    """The base step (tau) of a fresh run: fixed, or from the stability estimates at the initial shape X."""
    dt_f = formula_dt(cfg, edge_mean)
    if isinstance(cfg.dt, str) and cfg.scheme == "inextensible":
        # the stability limit of the bending force; the integrator adds tension, growth and flow limits
        dt = 2.0 * formula_dt(cfg, edge_mean, flow=False)
        if cfg.dt == "power":
            dt_p, lam = power_dt(solver, X)
            log.info("power iteration (bending): |lam|max = %.4g /tau -> dt_crit = %.4g tau", lam, dt_p)
            dt = min(dt_p, dt)
        return dt
    if isinstance(cfg.dt, str):
        if cfg.dt == "power":
            dt_p, lam = power_dt(solver, X)
            dt = cfg.dt_safety * min(dt_p, 2.0 * dt_f)
            log.info("power iteration: |lam|max = %.4g /tau -> dt_crit = %.4g tau (formula %.4g)", lam, dt_p, dt_f)
        else:
            dt = cfg.dt_safety * dt_f
        if cfg.chi > 0:
            dt = min(dt, 0.01 / cfg.chi)
        return dt
    return float(cfg.dt)
