"""Time integrators of the membrane, behind one small interface.

Every scheme is a class with ``step(state, X, F, geo, dt, rate) -> dX`` (the displacement of the vertices
over one step, background flow included) and ``next_dt(state, geo)`` (the step it wants next; fixed-step
schemes return their constant step). The coupled IBM enters only through the solver's mobility
(``velocity = M(X) F``, :class:`vesicle_core.solver.mobility.IBMMobility`) and, for the fixed-step schemes, the
time-integrated displacement of eq. (29) (finite Re).

* :class:`Explicit`: the paper's method, forward Euler with the stiff area penalty (A5).
* :class:`Projection`: explicit Euler plus a global tension multiplier that holds the total area exactly,
  with a 10x softer local penalty.
* :class:`Inextensible`: a tension per triangle solved every step from the linearised local area
  constraint (:mod:`vesicle_core.solver.tension`); no penalty stiffness, so the step follows the physics: the
  fastest wrinkle growth of the perturbation analysis, the bending and tension stability limits and the
  background flow.
  ``tension_space: harmonic`` carries the tension in real spherical harmonics instead
  (:mod:`vesicle_core.solver.tension_harmonic`), optionally with a tangential mesh motion (``mesh_ale: area``, or
  ``shape``, which also keeps the triangles' angles and carries the lipid area the mesh moves).
  ``noise_scheme: midpoint`` runs it as the stochastic midpoint method (:mod:`vesicle_core.solver.midpoint`, chosen by
  :func:`vesicle_core.solver.schemes.integrator_class`): two tension solves per step, second order without noise.
"""

from __future__ import annotations

import abc
import logging
import math

import numpy as np

from ..errors import ConfigError
from ..model.flow import background_velocity
from ..model.parameters import SCHEMES as SCHEME_NAMES
from ..model.resolution import DEFAULT_KERNEL
from ..xp import to_float

log = logging.getLogger("vesicle_core.solver.simulate")  # part of the run's log


class Integrator(abc.ABC):
    """Interface: a fixed step ``dt`` unless ``adaptive``; state kept on the run's State object."""

    name = "base"
    adaptive = False

    def __init__(self, solver, dt: float, X0=None):
        self.solver = solver
        self.cfg = solver.cfg
        self.dt = dt
        self.X0 = X0  # the reference mesh's vertices (material coordinates of tension_space: harmonic)

    def next_dt(self, state, geo) -> float:
        return self.dt

    def taken(self, dt: float) -> float:
        """The length of the step just taken by ``step`` asked for ``dt``: dt, unless the scheme shortened it (a
        rejected step of step_control error, embedded_midpoint)."""
        return dt

    @abc.abstractmethod
    def step(self, state, X, F, geo, dt, rate):
        """Displacement of the vertices over one step of length dt (background flow at ``rate`` included)."""

    def face_tension(self, state, geo):
        """Per-triangle tension for the output frames [kappa/R^2]."""
        from . import membrane as B

        mem = self.solver.membrane
        return B.local_tension(geo, mem.ref, mem.Lambda)

    def stats(self) -> dict:
        return {}


class Explicit(Integrator):
    """X^{n+1} = X^n + J Gamma^n + u_inf dt, eq. (29), with the penalty (A5) in F."""

    name = "explicit"

    def step(self, state, X, F, geo, dt, rate):
        dX = self.solver.induced_displacement(X, F, dt)
        if self.cfg.chi > 0:
            dX = dX + background_velocity(X, rate) * dt
        return dX


class Projection(Integrator):
    """Step with a global tension multiplier sigma_g that keeps the total area at A0.

    The membrane force gets the extra term -sigma_g grad A (a uniform tension). sigma_g is predicted
    from the previous step, then corrected by d_sigma so that the linearised area change of the step
    cancels the current area error: grad A . dX = A0 - A. The correction's flow uses w = M grad A,
    refreshed every ``projection_refresh`` steps (only the small correction d_sigma uses the cached
    w, so the error is second order). Costs one extra Stokes solve per refresh. w is the steady-Stokes
    response; at finite Re the main solve still uses the exponential update (23), and the correction's
    flow is then off by the fluid's inertial relaxation, O(Re) (Re ~ 2e-4 in the paper).
    """

    name = "projection"

    def step(self, state, X, F, geo, dt, rate):
        solver, cfg = self.solver, self.cfg
        xp = solver.xp
        A0 = solver.membrane.ref.area
        gradA = -geo.H  # (V, 3): dA/dX = -H, eq. (24)
        refresh = state.w is None or state.step % cfg.projection_refresh == 0
        if refresh:
            state.w = solver.induced_displacement(X, gradA, 1.0, advance=False)
        dX = solver.induced_displacement(X, F - state.sigma_g * gradA, dt, same_points=refresh)
        if cfg.chi > 0:
            dX = dX + background_velocity(X, rate) * dt
        A = to_float(geo.area.sum())
        d_sigma = (to_float(xp.sum(gradA * dX)) + (A - A0)) / (dt * to_float(xp.sum(gradA * state.w)))
        state.sigma_g += d_sigma
        return dX - (dt * d_sigma) * state.w

    def face_tension(self, state, geo):
        return super().face_tension(state, geo) + state.sigma_g


def fastest_growth_rate(sigma_mean: float, l_max: int, h: float = 0.0,
                        kernel: str = DEFAULT_KERNEL, coupling: str = "kernel") -> tuple[float, int]:
    """Largest growth rate -(Gamma_l + A_l sigma) (eq. 11) over 2 <= l <= l_max [1/tau] and its l.

    With h > 0 each rate is multiplied by the coupling's measured mode damping (model.resolution.mode_damping): the rate
    the IBM can actually produce on that grid, not the continuum's.
    """
    from ..model.modes import a_l, gamma_l
    from ..model.resolution import mode_damping

    l = np.arange(2, max(int(l_max), 2) + 1)
    r = -(gamma_l(l) + a_l(l) * sigma_mean)
    if h > 0:
        r = r * mode_damping(l, h, kernel, coupling)
    i = int(np.argmax(r))
    return float(r[i]), int(l[i])


# Largest eigenvalue of the linearised velocity under a uniform tension sigma: 0.11-0.125 sigma / h (power
# iteration, N = 64, 642 and 2562 vertices, sigma = 2000 and 8000; benchmarks/bench_tension.py). Forward
# Euler is stable for |lam| dt < 2, i.e. dt < 16 h / |sigma|. The sharp coupling does not smooth the mesh-scale
# modes away: 0.56 sigma / h at sigma = 8000 on 2379 vertices (edge ~h) at N = 64, so dt < 3.3 h / |sigma|.
TENSION_STABILITY = {"kernel": 16.0, "sharp": 3.3}
# steps between re-measurements of the bending limit: on the elongated vesicle at 128^3 (sharp coupling) it falls
# 4.8x from the start's while the wrinkles grow (|lam| 3.5e4 -> 1.7e5 /tau by gamma_dot t = 0.5 after the reversal),
# and steps at the start's limit then kicked vertices by up to 88 h
BENDING_REFRESH = 20


class Inextensible(Integrator):
    """Forward Euler with the tension solved from the local area constraint every step (module tension)."""

    name = "inextensible"
    adaptive = True
    strain_order = 2  # the step's area change beyond the linearised constraint is O(dt^2) (linearisation_strain)

    def __init__(self, solver, dt_bending: float, X0=None):
        from .mobility import IBMMobility
        from .tension import TensionSolver

        super().__init__(solver, dt_bending, X0)
        cfg = self.cfg
        self.dt_bending = dt_bending  # stability limit of the bending force (step_size.stiffest_mode), tau
        self.mobility = IBMMobility(solver.coupler, solver.stokes, solver._grid_buf)
        mem = solver.membrane
        local = None
        if cfg.cg_precond == "local":
            from .tension import LocalPreconditioner

            local = LocalPreconditioner(self.mobility, mem.topo, mem.ref.face_area, cfg.Lambda_eff,
                                        refresh=cfg.projection_refresh)
        self.space = None
        self.ale = None
        self._ref_host = None  # reference triangle areas and faces on the host (linearisation_strain)
        if cfg.tension_space == "harmonic":
            self.tension = self._harmonic_solver()
        else:
            self.tension = TensionSolver(self.mobility, mem.topo, mem.ref.face_area, cfg.Lambda_eff, tol=cfg.cg_tol,
                                         maxiter=cfg.cg_maxiter, cells="face", local=local)
        self.l_grid = math.ceil(math.pi / cfg.h)  # the shortest wave the grid can carry, in R
        self.iterations = []
        self._bending_step = -1  # step of the last bending-limit measurement
        self.bending_solves = 0  # Stokes solves spent on them (this call)
        self.bending_stokes_s = 0.0  # and those solves' wall time, their forces' differences left out
        self.dt_bending_min = self.dt_bending_last = dt_bending
        self.thermal = self._thermal() if cfg.kT > 0 else None
        # the noise's step limit, from the reference mesh so that a resumed run gets the same one
        self.dt_noise = math.inf
        if self.thermal is not None and X0 is not None:
            self.dt_noise = self.thermal.step_limit(self.solver.xp.asarray(X0), cfg.h, cfg.noise_step)
            log.info("thermal noise: rms displacement <= %g h per step -> dt <= %.4g tau", cfg.noise_step,
                     self.dt_noise)

    def _thermal(self):
        from . import membrane as B
        from .fluctuations import ConstrainedMobility, ThermalVelocity

        mem = self.solver.membrane
        def geometry(X):
            return B.geometry(X, mem.topo, mem.area_model)

        constrained = ConstrainedMobility(self.tension, self.mobility, geometry, harmonic=self.space is not None)
        return ThermalVelocity(self.solver.stokes, constrained, self.cfg.kT, self.cfg.noise_seed,
                               drift_every=self.cfg.noise_drift_every, scheme=self.cfg.noise_scheme)

    def _harmonic_solver(self):
        from .tension_harmonic import HarmonicSpace, HarmonicTensionSolver

        cfg, mem, be = self.cfg, self.solver.membrane, self.solver.be
        if self.X0 is None:
            raise ConfigError("tension_space 'harmonic' needs the reference mesh's vertices (X0) for its material "
                              "coordinates")
        faces = be.asnumpy(mem.topo.faces)
        self.space = HarmonicSpace(be.asnumpy(self.solver.xp.asarray(self.X0)), faces, be.asnumpy(mem.ref.face_area),
                                   cfg.tension_l_max)
        if cfg.mesh_ale == "area":
            from .mesh_ale import AreaALE

            self.ale = AreaALE(self.space, cfg.h)
        elif cfg.mesh_ale in ("shape", "quality"):
            from .mesh_ale import QualityALE, ShapeALE

            ale = ShapeALE if cfg.mesh_ale == "shape" else QualityALE
            self.ale = ale(self.space, cfg.h, be.asnumpy(self.solver.xp.asarray(self.X0)), faces)
        return HarmonicTensionSolver(self.mobility, mem.topo, self.space, cfg.Lambda_eff, tol=cfg.cg_tol,
                                     maxiter=cfg.cg_maxiter, hold_area=cfg.tension_fixed is None,
                                     secant=cfg.tension_preconditioner == "secant",
                                     # the solve's basis products in the grid's precision (HarmonicTensionSolver)
                                     basis_dtype=np.float32 if cfg.dtype == "float32" else None)

    def _start(self, c):
        """The solve's start coefficients: c, with the prescribed uniform tension in l = 0 (tension_fixed)."""
        if self.cfg.tension_fixed is not None:
            l0 = self.space.l == 0
            c[l0] = self.cfg.tension_fixed / self.space.B[0, l0]  # Y_00 is constant: B c is that tension everywhere
        return c

    def sigma_mean(self, state, geo) -> float:
        if state.sigma is None:
            return 0.0
        xp = self.solver.xp
        return to_float(xp.sum(state.sigma * geo.area) / xp.sum(geo.area))

    def next_dt(self, state, geo) -> float:
        cfg = self.cfg
        if state.step and state.step % BENDING_REFRESH == 0 and state.step != self._bending_step:
            self._measure_bending(state)
        limits = {"bending": cfg.dt_safety * self.bending_limit(state), "noise_step": self.dt_noise}
        if state.sigma is not None:
            smax = to_float(self.solver.xp.abs(state.sigma).max())
            if smax > 0:
                limits["tension"] = cfg.dt_safety * TENSION_STABILITY[cfg.coupling] * cfg.h / smax
            rate, _ = fastest_growth_rate(self.sigma_mean(state, geo), self.l_grid, cfg.h, cfg.kernel, cfg.coupling)
            if rate > 0:
                limits["growth"] = cfg.dt_growth / rate
        if cfg.chi > 0:
            # the background flow strains the vesicle by dt_growth / 10 per step (1% at the default 0.1)
            limits["flow"] = 0.1 * cfg.dt_growth / cfg.chi
        if state.strain_err > 0 and state.dt_steps:
            # the last step's area change beyond the linearised constraint: it scales as dt^strain_order
            limits["strain"] = state.dt_steps[-1] * (cfg.dt_strain / state.strain_err) ** (1.0 / self.strain_order)
        # named in the error when the step collapses, and recorded per frame (step_limits); the names are
        # step_limits.LIMITS
        self.limits, self.binding_limit = limits, min(limits, key=limits.get)
        return limits[self.binding_limit]

    def bending_limit(self, state) -> float:
        """The bending stability limit (tau): the last re-measurement's, or the start's before the first."""
        return state.dt_bending if state.dt_bending > 0 else self.dt_bending

    def _measure_bending(self, state) -> None:
        """Arnoldi iteration at the current shape, from the last measurement's vector (random, seeded by the step,
        at the first): the state carries both, so a resumed run measures what the first call did."""
        from .step_size import stiffest_mode

        t0 = self.solver.seconds
        lam, v, solves = stiffest_mode(self.solver, state.X, v0=state.bending_mode, max_iter=20, seed=state.step)
        self.bending_stokes_s += self.solver.seconds - t0
        self._bending_step = state.step
        self.bending_solves += solves
        if lam > 0:
            state.dt_bending, state.bending_mode = 2.0 / lam, v
            self.dt_bending_min = min(self.dt_bending_min, state.dt_bending)
            self.dt_bending_last = state.dt_bending

    def linearisation_strain(self, X, dX, geo_lin=None) -> float:
        """Largest strain of the held area (per triangle, or its W-projection on the harmonic space) that the step dX
        from X adds beyond first order: P (A(X + dX) - A(X) - D dX) / A^0, the change the linearised constraint
        cannot see. It scales as |dX|^2, so as dt^2; with D taken at ``geo_lin`` (the midpoint scheme's predicted
        midpoint), as dt^3. The CG's residual and an area error the step starts with are
        left out: neither shrinks with dt (the next solve corrects both), so a shorter step cannot reduce them."""
        from ..geometry.surface import triangle_area_nonlinear, triangle_areas
        from .tension import face_D

        be = self.solver.be
        if self._ref_host is None:  # constant: copied off the device once, not every step
            mem = self.solver.membrane
            self._ref_host = (be.asnumpy(mem.ref.face_area), be.asnumpy(mem.topo.faces))
        A0, faces = self._ref_host
        if geo_lin is None:
            e = triangle_area_nonlinear(be.asnumpy(X), faces, be.asnumpy(dX)) / A0
        else:
            Xh, dXh = (np.asarray(be.asnumpy(a), dtype=np.float64) for a in (X, dX))
            lin = np.asarray(be.asnumpy(face_D(dX, geo_lin, self.solver.membrane.topo)), dtype=np.float64)
            e = (triangle_areas(Xh + dXh, faces) - triangle_areas(Xh, faces) - lin) / A0
        if self.space is None:
            return float(np.abs(e).max())
        # the held part in coefficients; the l = 0 one only when the area is held
        d = self.space.fit(e)
        d[~self.tension.free] = 0.0
        return float(np.abs(self.space.faces(d)).max())

    def step(self, state, X, F, geo, dt, rate):
        cfg = self.cfg
        self._init_sigma(state, geo)
        self.mobility.prepare(X)
        u_known = background_velocity(X, rate) if cfg.chi > 0 else 0.0
        u_noise = None
        if self.thermal is not None:  # noise and drift: known velocities the constraint projects, like the flow's
            self._restore_rho(state)
            u_noise = self.thermal(X, dt, state.step)
            u_known = u_known + u_noise
        ref = self.held_area(state)
        _, sigma, U = self.tension_solve(state, geo, F, u_known, geo.area - ref, dt, self._warm_start(state), u_noise,
                                         state.tension_noise)
        self.iterations.append(self.tension.last.iterations)
        # measured on the membrane's own displacement, before the ALE's tangential one: that one is not a step of
        # the dynamics (the noise's area change scales as dt, so noisy runs are left to noise_step)
        strain = self.linearisation_strain(X, U * dt) if self.thermal is None else 0.0
        return self.finish_step(state, X, geo, sigma, U, dt, ref, strain)

    def _init_sigma(self, state, geo):
        if state.sigma is None:
            state.sigma = self.solver.xp.zeros(geo.area.shape[0])

    def held_area(self, state):
        """The area each triangle should have: the reference's, or the lipid area it carries (mesh_ale shape)."""
        return self.solver.membrane.ref.face_area if state.lipid_area is None else self.solver.xp.asarray(
            state.lipid_area)

    def tension_solve(self, state, geo, F, u_known, area_error, dt, start, u_noise, noise_c, coefficients=False):
        """One tension solve at geo's positions (the mobility prepared there) -> (coefficients or None, per-triangle
        tension, velocity U). ``start``: a per-triangle tension, or the space's coefficients when ``coefficients``
        (the triangle space ignores the flag); ``u_noise``, ``noise_c``: the harmonic solver's unpredicted part of
        u_known and the last solve's modelled noise response (HarmonicTensionSolver.solve)."""
        if self.space is None:
            sigma, U = self.tension.solve(geo, F, u_known, area_error, dt, start)
            return None, sigma, U
        ts = self._restore_rho(state)
        # a per-triangle guess lies in the space (both tensions are B c): its coefficients by the W projection
        c0 = start if coefficients else self._start(self.space.fit(self.solver.be.asnumpy(start)))
        return ts.solve(geo, F, u_known, area_error, dt, c0, seed=state.step, unpredicted=u_noise, noise_c=noise_c)

    def finish_step(self, state, X, geo, sigma, U, dt, ref, strain):
        """Keep the step's tension and solver state on ``state``; -> the displacement U dt plus the ALE's."""
        cfg, mem = self.cfg, self.solver.membrane
        if self.space is not None:
            ts = self.tension
            state.tension_rho, state.tension_rho_age, state.tension_noise = ts.rho, ts._uses, ts.noise_c
            state.tension_secant = None if ts.secant is None else ts.secant.R
        state.sigma_prev = state.sigma
        state.sigma = sigma
        state.dt_steps = (state.dt_steps[-1] if state.dt_steps else dt, dt)
        state.strain_err = strain
        if self.ale is None:
            return U * dt
        # tangential mesh motion holding the triangle areas outside the tension's space
        w = self.ale(X, geo, mem.topo, U * dt, geo.area - ref, scale=dt / (cfg.dt_safety * self.bending_limit(state)))
        if self.ale.carries_area:
            be = self.solver.be
            ref_host = be.asnumpy(ref) if state.lipid_area is None else state.lipid_area
            state.lipid_area = self.ale.carry(ref_host, be.asnumpy(X + U * dt), be.asnumpy(w), self.tension.free)
        return U * dt + w

    def _warm_start(self, state):
        """The CG's start tension: linear extrapolation in time of the last two (steps vary in length). With noise,
        the last one: the independent noise responses in the two would add up (start residual 9e-3 against 5e-3
        without it, 642 vertices at N = 32); with the secant model it loses its own noise response in the solve."""
        if state.sigma_prev is None or self.thermal is not None:
            return state.sigma
        h_a, h_b = state.dt_steps
        return state.sigma + (h_b / h_a) * (state.sigma - state.sigma_prev)

    def _restore_rho(self, state):
        """The harmonic solver, with its rho_l measurement of the first call when the run was resumed."""
        ts = self.tension
        if self.space is not None and ts.rho is None and state.tension_rho is not None:
            ts.rho, ts._uses = np.asarray(state.tension_rho, dtype=float), int(state.tension_rho_age)
            if ts.secant is not None and state.tension_secant is not None:
                ts.secant.R = np.array(state.tension_secant, dtype=float)
        return ts

    def face_tension(self, state, geo):
        if state.sigma is None:
            return self.solver.xp.zeros(geo.area.shape[0])
        return state.sigma

    def stats(self) -> dict:
        it = np.asarray(self.iterations, dtype=float)
        if it.size == 0:
            return {}
        return {"cg_iterations_median": float(np.median(it)), "cg_iterations_mean": float(it.mean()),
                "cg_iterations_max": int(it.max()),
                # one for the warm-start velocity, one per iteration (+ the harmonic space's rho_l measurements)
                "stokes_solves": int(it.size + it.sum() + getattr(self.tension, "extra_solves", 0)
                                     + self.bending_solves),
                # this call's wall time in the products M F through self.mobility: the step's, the tension's and
                # the thermal drift's (counted in thermal_stokes_solves), not the bending limit's
                "stokes_s": float(self.mobility.seconds),
                # the bending limit's products, timed alone (its solves are in stokes_solves)
                "bending_stokes_s": float(self.bending_stokes_s),
                "bending_solves": int(self.bending_solves), "dt_bending_min_tau": float(self.dt_bending_min),
                "dt_bending_last_tau": float(self.dt_bending_last),
                "cg_fallbacks": int(getattr(self.tension, "fallbacks", 0)),  # local -> compliance repeats (this call)
                **self._precond_stats(), **self._thermal_stats()}

    def _thermal_stats(self) -> dict:
        if self.thermal is None:
            return {}
        # this call's: the drift's constrained solves (two per step) and the noise fields drawn (one per step)
        return {"thermal_stokes_solves": int(self.thermal.stokes_solves),
                "thermal_noise_fields": int(self.thermal.noise.n_draws)}

    def _precond_stats(self) -> dict:
        if self.space is not None:
            out = {"tension_l_used": int(self.space.l_max), "tension_modes": int(self.space.K),
                   "tension_rho_refreshes": int(self.tension.refreshes)}
            if self.ale is not None:  # this call's
                out.update(ale_s=self.ale.seconds, ale_capped_steps=self.ale.capped)
            return out
        local = self.tension.local
        if local is None:
            return {}
        return {"cg_precond_factorisations": int(local.factorisations), "cg_precond_s": float(local.seconds),
                "cg_precond_shift": float(local.shift)}  # this call; the shift: the last build's (LocalPreconditioner)


#: scheme name -> integrator class; the names are the model's (model.parameters.SCHEMES), each class carries its own
SCHEMES = {cls.name: cls for cls in (Explicit, Projection, Inextensible)}

# a scheme RunConfig accepts but no class runs (or the reverse) fails here, at import
if tuple(SCHEMES) != SCHEME_NAMES:
    raise RuntimeError(f"integrators {tuple(SCHEMES)} do not match the schemes of model.parameters {SCHEME_NAMES}")
