r"""The inextensible scheme as an embedded Euler/midpoint pair with error control (run parameter
``step_control: error``).

One step of length dt from X^n, without noise:

    U0    = N(X^n) F(X^n) + P u_inf(X^n)                       tension solve at X^n, holding the area over dt
    X'    = X^n + dt/2 U0                                      the predicted midpoint
    U_mid = N(X') F(X') + P u_inf(X')                          tension solve at X', holding the area change from X^n
    X^{n+1} = X^n + dt U_mid                                   explicit midpoint (RK2), second order
    e     = dt (U_mid - U0) = dt^2 / 2 dU/dt + O(dt^3)         the first-order (Euler) step's local error

The predictor's velocity U0 is today's forward-Euler step (the solve holds the area error over dt, as
:class:`~vesicle_core.solver.integrators.Inextensible` does), so the pair costs nothing beyond the midpoint scheme's
two tension solves. The estimate is that of the first-order solution and the run advances with the second-order one
(local extrapolation, as scipy's RK23 does), so the tolerance is conservative for the step taken.

``err`` = :class:`~vesicle_core.solver.step_control.WrinkleNorm` of e: the normal part of the error against
``step_tol`` times the wrinkles' own amplitude, and the shape's. A step with err > 1 is redone from X^n with a
shorter dt (:class:`~vesicle_core.solver.step_control.StepController`); a rejected attempt writes nothing on the run's
State (its tension, warm start, ALE and lipid area are set only by the accepted attempt through ``finish_step``), and
the driver advances the time by the step actually taken (:meth:`taken`). The next step the controller wants is kept
on the State (``dt_error``, checkpointed), so a resumed run steps as an uninterrupted one. In ``next_dt`` it replaces
the accuracy limits ``growth`` and ``flow`` (recorded as the ``error`` limit); the stability limits (bending, tension)
and the linearised constraint's ``strain`` still apply, the smallest of them sets the step. The first step of the
run and the first after the reversal (the seed and the flow's reversal change the dynamics at once) start from the
growth and flow limits, as scipy starts from an estimated first step.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from ..geometry.surface import vertex_normals
from ..model.flow import background_velocity
from . import step_limits
from .midpoint import MidpointInextensible
from .step_control import StepController, WrinkleNorm

#: the accuracy limits the controller replaces
REPLACED = ("growth", "flow")


class EmbeddedMidpoint(MidpointInextensible):
    """The inextensible scheme, explicit midpoint with an embedded Euler error estimate (module docstring)."""

    def __init__(self, solver, dt_bending: float, X0=None):
        super().__init__(solver, dt_bending, X0)
        be, mem = solver.be, solver.membrane
        if X0 is None:
            raise ConfigError("step_control 'error' needs the reference mesh's vertices (X0) for its band split")
        faces = self._faces = be.asnumpy(mem.topo.faces)
        # each vertex's third of its triangles' reference areas: the weights of the rms
        weights = np.bincount(faces.ravel(), weights=np.repeat(be.asnumpy(mem.ref.face_area) / 3.0, 3),
                              minlength=mem.topo.n_vertices)
        self.norm = WrinkleNorm(be.asnumpy(solver.xp.asarray(X0)), weights, self.cfg.h, self.cfg.step_tol)
        self.controller = StepController(order=1)
        self._dt_taken = None
        self.rejected = 0  # rejected attempts (this call)
        self.rejected_solves = 0  # Stokes solves they cost (this call)
        self.last_err = math.nan
        self.estimate = None  # the last attempt's error estimate dt (U_mid - U0), (V, 3)

    def next_dt(self, state, geo) -> float:
        dt = super().next_dt(state, geo)
        if not state.dt_error > 0:  # the run's first step: the old limits' step as the guess
            return dt
        limits = {k: v for k, v in self.limits.items() if k not in REPLACED}
        limits["error"] = state.dt_error
        self.limits, self.binding_limit = limits, min(limits, key=limits.get)
        return limits[self.binding_limit]

    def taken(self, dt: float) -> float:
        return self._dt_taken if self._dt_taken is not None else dt

    def step(self, state, X, F, geo, dt, rate):
        cfg, mem = self.cfg, self.solver.membrane
        first = state.sigma is None  # no tension yet: the zeros _init_sigma puts there are not one
        self._init_sigma(state, geo)
        ref = self.held_area(state)
        area_error = geo.area - ref
        sigma_rate = self._sigma_rate(state)
        start = self._warm_start(state)
        normals = None
        rejected_here = False
        while True:
            self.mobility.prepare(X)
            u_known = background_velocity(X, rate) if cfg.chi > 0 else 0.0
            c, sigma0, U0 = self.tension_solve(state, geo, F, u_known, area_error, dt, start, None,
                                               state.tension_noise)
            iterations = self.tension.last.iterations
            Xh = X + (0.5 * dt) * U0
            Fh, geoh = self.solver.forces(Xh)
            self.mobility.prepare(Xh)
            u_known = background_velocity(Xh, rate) if cfg.chi > 0 else 0.0
            # the velocity at the midpoint needs the midpoint's tension, the compliance W sigma / Lambda the end's:
            # the end's is the midpoint's plus dt/2 sigma' (the last steps' rate)
            lead = 0.0 if sigma_rate is None else mem.ref.face_area * sigma_rate * (0.5 * dt / cfg.Lambda_eff)
            _, sigma, U = self.tension_solve(state, geoh, Fh, u_known, area_error - lead, dt,
                                             sigma0 if c is None else c, None, getattr(self.tension, "noise_c", None),
                                             coefficients=True)
            iterations += self.tension.last.iterations
            be = self.solver.be
            if normals is None:
                normals = vertex_normals(be.asnumpy(X), self._faces)
            self.estimate = (U - U0) * dt  # the Euler step's local error, to leading order
            err = self.norm(be.asnumpy(X), normals, be.asnumpy(self.estimate))
            if err <= 1.0 or not self.adaptive:
                break
            # rejected: nothing of this attempt is kept on the state; retry from X^n with a shorter step
            self.rejected += 1
            self.rejected_solves += 2 + iterations  # as stats() counts an accepted step's
            rejected_here = True
            dt = dt * self.controller.reject_factor(err)
            step_limits.rejected(state, dt)
        self._dt_taken = dt
        self.last_err = err
        state.dt_error = dt * self.controller.accept_factor(err, rejected_here)
        self.iterations.append(iterations)
        strain = self.linearisation_strain(X, U * dt, geo_lin=geoh)
        sigma_end = sigma if sigma_rate is None else sigma + (0.5 * dt) * sigma_rate
        dX = self.finish_step(state, X, geo, sigma_end, U, dt, ref, strain)
        if first:
            state.sigma_prev = None
        return dX

    @staticmethod
    def _sigma_rate(state):
        """d sigma / dt from the last two steps' end tensions; None before there are two, and where the earlier one
        is not after the reversal (the tension jumps with the flow there)."""
        if state.sigma_prev is None or not state.dt_steps:
            return None
        if state.phase == "relax" and not state.t - state.dt_steps[-1] > state.t_reverse:
            return None
        return (state.sigma - state.sigma_prev) * (1.0 / state.dt_steps[-1])

    def stats(self) -> dict:
        out = super().stats()
        out["steps_rejected"] = int(self.rejected)
        if "stokes_solves" in out:
            out["stokes_solves"] += int(self.rejected_solves)
        return out
