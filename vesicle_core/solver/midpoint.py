r"""The inextensible scheme as a stochastic midpoint method (run parameter ``noise_scheme: midpoint``).

Delong, Usabiaga, Delgado-Buscalioni, Griffith & Donev, J. Chem. Phys. 140, 134110 (2014), the "simple midpoint"
scheme of the fluctuating immersed boundary method, with this project's tension constraint in both solves. With
N(X) = P J A S P^T the constrained mobility (:class:`~vesicle_core.solver.fluctuations.ConstrainedMobility`), z1, z2
two independent white-noise grid fields and W the random finite difference's vector, one step of length dt is

    predictor   X' = X^n + dt/2 [N F + P u_inf + P J sqrt(2 kT / (dt/2) / h^3) A^{1/2} z1]        (P, J at X^n)
    corrector   X^{n+1} = X^n + dt [N F + P u_inf + P J (sqrt(kT dt / h^3) A^{1/2} (z1 + z2) / dt + A g)]   (at X')
    drift field g = (kT / delta) (S P^T W |_{X^n + delta W/2} - S P^T W |_{X^n - delta W/2})

with every P a tension solve (the corrector's linearised at X' and holding the area change from X^n, since
A(X^{n+1}) - A(X^n) = D(midpoint) (X^{n+1} - X^n) to third order). The corrector's noise, evaluated at the predicted
midpoint, carries in the mean the part of the Ito drift kT div_X N in which the derivative acts on P J; the random
finite difference of the spreading (:meth:`~vesicle_core.solver.fluctuations.ThermalVelocity.spread_drift`) carries
the part on S P^T. So the scheme is weakly first-order consistent with dX = (N F + kT div N) dt + sqrt(2 kT) N^{1/2}
dW like Euler-Maruyama with the full drift (``tests/solver/test_midpoint.py`` measures the step's mean against
kT div N). On a 42-vertex vesicle the corrector alone carries the drift (regression slope 0.976 +- 0.021, 0.983
with g): the constraint's projection P varies fastest, and g is nearly the spread of a gradient, which the Leray
projector removes. Without noise it is the second-order explicit midpoint (RK2) method:
its area change beyond the linearised constraint is O(dt^3) (``strain_order``). For a linear mode relaxing at rate
a, its stationary variance is (kT / k) (1 + (a dt)^3 / 8 + ...), exact to third order (Euler's is off at first
order, lm's is exact). ``noise_drift_every: 0`` leaves out the random finite difference (g, the part of the drift on
S P^T); the corrector's part stays.

Cost: two tension solves per step (Euler-Maruyama's one), the forces at the predicted midpoint, two noise fields,
and, on drift steps, two constrained solves plus one Stokes solve. Same stability limits as forward Euler.
"""

from __future__ import annotations

from ..model.flow import background_velocity
from .integrators import Inextensible


class MidpointInextensible(Inextensible):
    """The inextensible scheme with a predictor half step and a corrector from the predicted midpoint (module
    docstring); state, stability limits and output as :class:`~vesicle_core.solver.integrators.Inextensible`."""

    strain_order = 3  # the corrector's linearisation at the midpoint leaves O(dt^3) (linearisation_strain)

    def step(self, state, X, F, geo, dt, rate):
        cfg, th = self.cfg, self.thermal
        coupler = self.mobility.coupler
        self._init_sigma(state, geo)
        ref = self.held_area(state)
        area_error = geo.area - ref  # both solves hold the area change from X^n
        # predictor: half a step with the first half of the Brownian increment
        self.mobility.prepare(X)
        u_known = background_velocity(X, rate) if cfg.chi > 0 else 0.0
        u_noise = None
        if th is not None:
            self._restore_rho(state)
            half1, half2 = th.half_increments(dt, state.step)
            u_noise = coupler.interpolate(half1) * (2.0 / dt)
            u_known = u_known + u_noise
        c, sigma, U = self.tension_solve(state, geo, F, u_known, area_error, 0.5 * dt, self._warm_start(state),
                                         u_noise, state.tension_noise)
        iterations = self.tension.last.iterations
        noise_c = getattr(self.tension, "noise_c", None)
        Xh = X + (0.5 * dt) * U
        Fh, geoh = self.solver.forces(Xh)
        u_grid = None
        if th is not None:  # the whole increment, and the drift's finite difference taken at X^n
            u_grid = (half1 + half2) * (1.0 / dt)
            drift = th.spread_drift(X, dt, state.step)
            if drift is not None:
                u_grid += drift
        # corrector: the whole step, linearised at the predicted midpoint
        self.mobility.prepare(Xh)
        u_known = background_velocity(Xh, rate) if cfg.chi > 0 else 0.0
        u_noise = None
        if u_grid is not None:
            u_noise = coupler.interpolate(u_grid)
            u_known = u_known + u_noise
        _, sigma, U = self.tension_solve(state, geoh, Fh, u_known, area_error, dt, sigma if c is None else c, u_noise,
                                         noise_c, coefficients=True)
        self.iterations.append(iterations + self.tension.last.iterations)
        strain = self.linearisation_strain(X, U * dt, geo_lin=geoh) if th is None else 0.0
        return self.finish_step(state, X, geo, sigma, U, dt, ref, strain)

    def stats(self) -> dict:
        # two tension solves per step, each one warm-start velocity plus one per iteration (recorded summed)
        out = super().stats()
        if "stokes_solves" in out:
            out["stokes_solves"] += len(self.iterations)
        return out
