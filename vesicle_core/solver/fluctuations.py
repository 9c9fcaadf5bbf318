r"""Thermal velocity noise of the fluctuating immersed boundary method, balanced against this grid's own mobility.

Fluctuation-dissipation on the collocated grid
----------------------------------------------
The steady coupled mobility of :class:`~vesicle_core.solver.mobility.IBMMobility` is

    M = J A S,    A = xi W / lam   (symbol per mode: xi_k W_k / lam_k, zero at k = 0, xi_k = I where g_k = 0)

with J the interpolation (plain weighted sum), S = J^T / h^3 the spreading (:mod:`vesicle_core.solver.ibm`), lam_k and
g_k the symbols of the 7-point Laplacian and of the central-difference gradient, xi_k = I - g g^T / |g|^2 the
discrete Leray projector and W the optional force filter of the sharpened coupling (1 without it)
(:mod:`vesicle_core.solver.stokes`). A is real, symmetric and positive semi-definite on the grid, and its symmetric
square
root is A^{1/2} = xi (W / lam)^{1/2} (xi is a projector commuting with the scalar W / lam): the solver's
:meth:`~vesicle_core.solver.stokes.StokesSolver.sqrt_velocity`. The noise displacement field over a step dt is

    dU = sqrt(2 kT dt / h^3) A^{1/2} z,     z white: independent N(0, 1) per node and component,

and its interpolation J dU to any Lagrangian points has covariance

    2 kT dt / h^3 J A^{1/2} A^{1/2} J^T = 2 kT dt J A (J^T / h^3) = 2 kT dt J A S = 2 kT dt M

exactly, for every configuration and both couplings (``W``: sqrt(W) in the noise symbol). The Fourier symbol is
applied to the real FFT of real white noise, so the half spectrum's Hermitian symmetry is kept by the real
inverse FFT, the k = 0 mode is zero (no mean flow, as in the deterministic solve) and the 7 Nyquist-type modes
get the identity projector, like the deterministic solve. Nothing here uses a staggered-grid stochastic stress:
on this collocated grid |g_k|^2 != lam_k, and the divergence of a white stress would give the wrong covariance
(``tests/solver/test_fluctuations.py`` shows such a symbol failing the test). Cost: one 3-component FFT round trip and
3 N^3 normal deviates per step.

Units: kT in kappa (the solver units, mu = 1, lengths in R, time in tau = mu R^3 / kappa), so kT = k_B T / kappa
(0.0405 at 293 K, kappa = 1e-19 J). kT = 0 gives a zero field.

Reproducible numbers
--------------------
:func:`noise_generator` returns ``numpy.random.Generator(Philox)`` keyed by the seed, its counter starting at
[0, 0, step, stream]: a counter-based stream, so the numbers of a step depend only on (seed, step, stream), never
on what was drawn before (a resumed run draws the same noise; steps use disjoint counter ranges up to 2^64 blocks
of 4 words per step). The deviates are drawn on the host in the backend's dtype (float32 and float64 draws
differ) and copied to the device on CuPy, so NumPy and CuPy runs get the same numbers.

Step
----
``euler`` (Euler-Maruyama) gives every step its own white noise z_n. Its stationary distribution is off by O(dt): a
linear mode relaxing at rate a has the variance (kT / k) / (1 - a dt / 2), so the fast modes of a tense vesicle
(a ~ 300-450 / tau at sigma = 600 on a 642-vertex mesh at N = 32) are 7-13% too large at dt = 5e-4 tau
(docs/history/thermal.md,
section 7). ``lm`` gives step n the mean (z_n + z_{n+1}) / 2 with the same amplitude (Leimkuhler & Matthews, Appl.
Math. Res. Express 2013; Leimkuhler, Matthews & Stoltz, IMA J. Numer. Anal. 36, 13 (2016)): the sum of the steps'
noise is the same Brownian path up to the end terms, and for x_{n+1} = (1 - a dt) x_n + sqrt(2 D dt) (z_n + z_{n+1})
/ 2 the stationary variance is D / a exactly at every stable dt (the Euler bias cancels; for a non-linear potential
it is second order). Same cost: one more 3 N^3 draw, one FFT set. Numbers: those of steps n and n + 1 of the same
counter-based stream, so a resumed run draws the same ones.

``midpoint`` is the simple midpoint scheme of Delong et al. (2014), an integrator of its own
(:class:`vesicle_core.solver.midpoint.MidpointInextensible`): the step's Brownian increment is split into two halves
z1, z2 (streams 0 and 2 of the step), the predictor moves half a step with z1, the corrector the whole step with
z1 + z2 from the predicted midpoint. Two tension solves per step.

Drift
-----
A configuration-dependent mobility adds the drift kT div_X M to the Ito equation (Delong et al., J. Chem. Phys.
140, 134110 (2014)). :func:`mobility_divergence` measures it by central differences (6 n solves; a reference);
:func:`rfd_drift` is their random finite difference (two solves, unbiased in the mean), the form an integrator
uses. docs/history/thermal.md reports the drift's size for this kernel and grid: it does not vanish on a membrane.
"""

from __future__ import annotations

import numpy as np

from ..errors import check_choice, check_range
from ..errors import check_counter as _check_counter

#: how a step's white noise is drawn (run parameter noise_scheme; module docstring, "Step")
NOISE_SCHEMES = ("euler", "lm", "midpoint")


#: noise on markers closer than this many grid spacings is warned of: at a fixed tension the 2562-vertex mesh at N = 32
#: (edge 0.48 h) grew its area by 1.6% over 2.9 tau and stopped on a CG failure, where 642 vertices (edge ~h) held it
#: to 3e-4 (docs/history/thermal.md, section 7); the grid neither moves nor damps such markers apart
NOISE_EDGE_MIN = 0.5


def noise_mesh_warning(edge_over_h):
    """The warning for thermal noise on a mesh whose mean edge is ``edge_over_h`` grid spacings, or None."""
    if edge_over_h >= NOISE_EDGE_MIN:
        return None
    return (f"kT > 0 with a mean mesh edge of {edge_over_h:.2f} h (< {NOISE_EDGE_MIN} h): at 0.48 h a fixed-tension "
            "run's area grew by 1.6% in 2.9 tau and its tension solve then failed "
            "(docs/history/thermal.md, section 7); use a mesh of edge ~h or a finer grid")


def noise_generator(seed, step, stream=0):
    """The generator of one step's noise: ``Generator(Philox(key=seed, counter=[0, 0, step, stream]))``.

    seed : integer in [0, 2^64 - 1] (the run's noise seed); step : the step counter, integer >= 0; stream : an
    integer tag separating independent uses within one step (0: the velocity noise).
    """
    seed = _check_counter("seed", seed)
    step = _check_counter("step", step)
    stream = _check_counter("stream", stream)
    counter = np.array([0, 0, step, stream], dtype=np.uint64)
    return np.random.Generator(np.random.Philox(key=seed, counter=counter))


class ThermalNoise:
    """Fluctuating-Stokes noise on one :class:`~vesicle_core.solver.stokes.StokesSolver` (module docstring).

    ``displacement(dt, step)`` is the grid field sqrt(2 kT dt / h^3) xi (W / lam)^{1/2} z whose interpolation to
    the membrane (``coupler.interpolate``) is the thermal displacement over dt, covariance 2 kT dt M. The
    corresponding velocity is that field / dt (covariance 2 kT M / dt).

    stokes : the run's StokesSolver (its grid, backend, symbols and force filter W are used as they are).
    kT : k_B T / kappa >= 0. seed : integer in [0, 2^64 - 1].
    """

    def __init__(self, stokes, kT, seed=0, scheme="euler"):
        self.scheme = check_choice("noise_scheme", scheme, NOISE_SCHEMES)
        self.stokes = stokes
        self.grid = stokes.grid
        self.backend = stokes.backend
        self.kT = float(check_range("kT", kT, 0.0, None))
        self.seed = _check_counter("seed", seed)
        self.dtype = np.dtype(self.backend.dtype)
        self._host = None  # host buffer of the white noise (reused)
        self._pair = None  # lm: two host buffers, the first holding step _next_step's draw after a call
        self._next_step = None
        self.n_draws = 0

    def amplitude(self, dt):
        """sqrt(2 kT dt / h^3): the factor in front of A^{1/2} z."""
        dt = float(check_range("dt", dt, 0.0, None, lo_open=True))
        return float(np.sqrt(2.0 * self.kT * dt / self.grid.h**3))

    def white(self, step, stream=0, out=None):
        """z: independent N(0, 1) per node and component, (3, N, N, N) host array of the backend dtype, drawn by
        :func:`noise_generator` (seed, step, stream) into ``out`` or a buffer that the next call overwrites."""
        if out is None:
            if self._host is None:
                self._host = np.empty(self.grid.field_shape, dtype=self.dtype)
            out = self._host
        noise_generator(self.seed, step, stream).standard_normal(dtype=self.dtype, out=out)
        self.n_draws += 1
        return out

    def displacement(self, dt, step, out=None, stream=0):
        """Grid field (3, N, N, N) of the thermal displacement over dt at step ``step`` (backend array).

        Interpolated to any points X it has mean 0 and covariance 2 kT dt M(X); zero when kT = 0.
        ``out``: a grid buffer to write into (as in ``StokesSolver.velocity``). ``stream``: the generator's
        stream (0: the run's noise; others are independent draws of the same step).
        """
        scale = self.amplitude(dt)
        if scale == 0.0:
            if out is None:
                return self.backend.zeros(self.grid.field_shape)
            out[...] = 0
            return out
        z = self.white(step, stream)
        if self.backend.is_gpu:  # same numbers as on NumPy: drawn on the host, copied
            z = self.backend.asarray(z, dtype=self.dtype)
        return self.stokes.sqrt_velocity(z, scale, out=out)

    def velocity(self, dt, step, out=None):
        """The noise velocity of the step: displacement / dt (covariance 2 kT M / dt after interpolation) with the
        scheme ``euler``; with ``lm`` the same operator on the mean of this step's and the next step's white noise,
        (z_step + z_step+1) / 2 (Leimkuhler & Matthews), whose increments sum to the same Brownian path."""
        if self.scheme == "euler":
            u = self.displacement(dt, step, out=out)
        else:  # step n + 1's draw is kept for the next call: half the host draws, the same numbers, no allocation
            if self._pair is None:
                self._pair = [np.empty(self.grid.field_shape, dtype=self.dtype) for _ in range(2)]
            z, nxt = self._pair
            if self._next_step != step:  # not drawn by the last call: the first step, or a resumed run's
                self.white(step, out=z)
            self.white(step + 1, out=nxt)
            self._pair, self._next_step = [nxt, z], step + 1
            z += nxt  # the mean, in the buffer the next call draws into
            z *= 0.5
            if self.backend.is_gpu:
                z = self.backend.asarray(z, dtype=self.dtype)
            u = self.stokes.sqrt_velocity(z, self.amplitude(dt), out=out)
        u *= 1.0 / float(dt)
        return u


def mobility_matrix(mobility, X):
    """Dense M(X) (3 n, 3 n) of an :class:`~vesicle_core.solver.mobility.IBMMobility` at the points X (n, 3), by unit
    forces (3 n Stokes solves), as a float64 host array; index 3 i + c is point i, component c."""
    xp = mobility.backend.xp
    X = np.asarray(X, dtype=np.float64)
    n = X.shape[0]
    mobility.prepare(xp.asarray(X))
    out = np.empty((3 * n, 3 * n))
    for j in range(3 * n):
        F = np.zeros((n, 3))
        F.flat[j] = 1.0
        out[:, j] = mobility.backend.asnumpy(mobility.apply(xp.asarray(F))).reshape(-1)
    return out


def mobility_divergence(mobility, X, eps=1e-4):
    """div_X M at the points X (n, 3): (div M)_i = sum_j d M_ij / d X_j, by central differences of step eps (in
    the grid's length unit), 6 n Stokes solves; returns (n, 3). kT times this is the Ito drift of the
    overdamped equation dX = M F dt + kT div M dt + sqrt(2 kT dt) M^{1/2} dW."""
    xp = mobility.backend.xp
    X = np.asarray(X, dtype=np.float64)
    n = X.shape[0]
    div = np.zeros(3 * n)
    for j in range(3 * n):
        F = np.zeros((n, 3))
        F.flat[j] = 1.0
        col = []
        for s in (1.0, -1.0):
            Xs = X.copy()
            Xs.flat[j] += s * eps
            mobility.prepare(xp.asarray(Xs))
            col.append(mobility.backend.asnumpy(mobility.apply(xp.asarray(F))).reshape(-1))
        div += (col[0] - col[1]) / (2.0 * eps)
    return div.reshape(n, 3)


def rfd_drift(mobility, X, kT, seed, step, delta=1e-4, stream=1):
    """Random finite difference of the Ito drift (Delong et al. 2014): kT / delta [M(X + delta W / 2) W -
    M(X - delta W / 2) W] with W (n, 3) standard normal from :func:`noise_generator` (seed, step, ``stream``; stream
    1 by default, independent of the velocity noise's stream 0). Its mean over W is kT div_X M + O(delta^2); two
    Stokes solves. delta in the grid's length unit (R), small against h. Leaves the mobility prepared at
    X - delta W / 2: call ``mobility.prepare(X)`` again before using it at X."""
    kT = float(check_range("kT", kT, 0.0, None))
    delta = float(check_range("delta", delta, 0.0, None, lo_open=True))
    xp = mobility.backend.xp
    X = np.asarray(X, dtype=np.float64)
    W = noise_generator(seed, step, stream).standard_normal(X.shape)
    out = []
    for s in (0.5, -0.5):
        mobility.prepare(xp.asarray(X + s * delta * W))
        out.append(mobility.backend.asnumpy(mobility.apply(xp.asarray(W))))
    return kT / delta * (out[0] - out[1])


class ConstrainedMobility:
    """N(X): the velocity that forces W give under the run's tension constraint, U = M (W - D^T sigma) with sigma
    such that the tension space sees no area change (the tension solve with no background flow and no area error).

    Same ``prepare(X)`` / ``apply(W)`` / ``backend`` interface as :class:`~vesicle_core.solver.mobility.IBMMobility`,
    so :func:`rfd_drift` and :func:`mobility_divergence` measure kT div_X N, the drift of the constrained dynamics.
    ``tension``: the run's TensionSolver or HarmonicTensionSolver; ``geometry``: X -> membrane Geometry.
    """

    def __init__(self, tension, mobility, geometry, harmonic: bool):
        self.tension = tension
        self.mobility = mobility
        self.backend = mobility.backend
        self.geometry = geometry
        self.harmonic = harmonic
        self._geo = None
        self.dt = 1.0  # the step the constraint's compliance is scaled with (set to the run's step before use)
        self.step = 0  # the draw of a harmonic solver's rho_l measurement, when one falls due

    def prepare(self, X):
        self.mobility.prepare(X)
        self._geo = self.geometry(X)

    def _solve(self, W):
        """(per-triangle tension, velocity) of the constrained solve for forces W at the prepared positions."""
        geo, xp = self._geo, self.backend.xp
        zero_area = xp.zeros(geo.area.shape[0], dtype=geo.area.dtype)
        if self.harmonic:
            c0 = np.zeros(self.tension.space.K)
            return self.tension.solve(geo, W, 0.0, zero_area, self.dt, c0, seed=self.step, warm=False)[1:]
        return self.tension.solve(geo, W, 0.0, zero_area, self.dt, zero_area)

    def force(self, W):
        """P^T W = W - D^T sigma: the forces W plus the tension they raise under the constraint (what the membrane
        exerts on the fluid; ``apply`` is M of it)."""
        from .tension import face_DT

        return W - face_DT(self._solve(W)[0], self._geo, self.tension.topo)

    def apply(self, W):
        return self._solve(W)[1]


class ThermalVelocity:
    """The thermal part of an inextensible step's velocity: the fluctuating Stokes noise interpolated at X
    (covariance 2 kT M / dt) plus the Ito drift kT div_X N of the constrained mobility by random finite differences
    (:func:`rfd_drift`, two constrained solves). Both go into the tension solve as a known velocity, beside the
    background flow, so the constraint projects them: the noise the membrane sees has the constrained mobility's
    covariance 2 kT N / dt (P M P^T = N for the M-orthogonal projection P = I - M D^T (D M D^T)^-1 D).

    Euler-Maruyama with this drift is weakly first-order consistent for the Ito equation
    dX = (N F + kT div N) dt + sqrt(2 kT) N^{1/2} dW (Delong et al. 2014). The constraint is the tension space's
    linearised local one, solved exactly up to the CG tolerance (a rigid constraint, not the stiff-spring limit:
    Hinch 1994 shows the two sample different shape measures).
    """

    def __init__(self, stokes, constrained: ConstrainedMobility, kT, seed, delta=None, drift_every=1,
                 scheme="euler"):
        self.noise = ThermalNoise(stokes, kT, seed, scheme)
        # the drift's random finite difference on every drift_every-th step only, weighted by it: its mean per unit
        # time is kept and the noise's cost falls from two constrained solves per step to 2 / drift_every; the
        # displacement it adds scatters by O(dt) per application, against the noise's O(sqrt(dt)); exact in the mean
        # for a fixed dt, to first order for an adaptive step that changes slowly. 0 switches the drift off: a paired
        # run at N = 32 (same noise) moved neither the spectrum nor the centroid's D (docs/history/thermal.md section 7)
        self.drift_every = int(check_range("drift_every", drift_every, 0, None))
        self.constrained = constrained
        self.kT = self.noise.kT
        self.seed = self.noise.seed
        # small against the grid spacing, large against round-off of float32 positions (~1e-7 R)
        self.delta = float(delta) if delta is not None else 1e-3 * stokes.grid.h
        self.stokes_solves = 0  # those of the drift's constrained solves (the noise itself is one FFT round trip)

    def self_mobility(self, X, n_draws=4):
        """m_self (1/mu): the markers' mean self-mobility per component, E|J dU|^2 / (3 V 2 kT dt) averaged over the
        V markers X and ``n_draws`` independent draws (key 0 whatever the run's seed, stream 3, steps 0, 1, ...; the
        run's noise is untouched). A function of X and the grid only, so a resumed run, and every seed of an
        ensemble, gets the same value. Leaves the mobility prepared at X. ~ 1 / (6 pi mu a_h) with a_h the
        coupling's hydrodynamic radius, less the periodic images."""
        mob = self.constrained.mobility
        xp = mob.backend.xp
        mob.prepare(xp.asarray(X))
        probe = ThermalNoise(self.noise.stokes, self.kT, 0)
        total = 0.0
        for k in range(int(n_draws)):
            d = mob.coupler.interpolate(probe.displacement(1.0, k, stream=3))
            total += float(xp.mean(d.astype(xp.float64) ** 2))
        return total / int(n_draws) / (2.0 * self.kT)

    def step_limit(self, X, h, max_step):
        """Longest dt (tau) whose rms noise displacement per component, sqrt(2 kT dt m_self), is ``max_step`` h."""
        check_range("noise_step", max_step, 0.0, None, lo_open=True)
        return (float(max_step) * float(h)) ** 2 / (2.0 * self.kT * self.self_mobility(X))

    def half_increments(self, dt, step):
        """The midpoint scheme's noise: two grid displacement fields over dt / 2 each, sqrt(kT dt / h^3) A^{1/2} z1
        and the same of z2 (streams 0 and 2 of the step), whose sum is one Brownian increment over dt (covariance
        2 kT dt M after interpolation)."""
        # each call returns a new array (the inverse FFT's output), so the first survives the second draw
        return (self.noise.displacement(0.5 * dt, step, stream=0),
                self.noise.displacement(0.5 * dt, step, stream=2))

    def spread_drift(self, X, dt, step):
        """The midpoint scheme's random finite difference: the grid velocity L^{-1} xi of the force field
        (kT / delta) [S(X+) P^T(X+) W - S(X-) P^T(X-) W], X+- = X +- delta W / 2, W from stream 1 of the step (two
        constrained solves, one Stokes solve), weighted by drift_every; None on steps without a drift.

        In the mean it is kT J A d_k (S P^T)_{.k}: the term of kT div_X N = kT div_X (P J A S P^T) in which the
        derivative acts on the right-hand factor. The corrector's noise, P J A^{1/2} (z1 + z2) interpolated and
        projected at the predicted midpoint, supplies the other term, the derivative of the left-hand factor P J
        (Delong et al. 2014, the midpoint scheme; here with the constraint's projection P in both factors). On the
        test vesicle this term is below the sampling error of the drift (tests/solver/test_midpoint.py)."""
        if not self.drift_every or step % self.drift_every:
            return None
        con = self.constrained
        be, coupler = con.backend, con.mobility.coupler
        con.dt, con.step = dt, step
        X = np.asarray(be.asnumpy(X), dtype=np.float64)
        W = noise_generator(self.seed, step, 1).standard_normal(X.shape)
        n0 = con.mobility.n_products
        grid = None
        for s in (0.5, -0.5):
            con.prepare(be.asarray(X + s * self.delta * W))
            f = con.force(be.asarray(W, dtype=con._geo.area.dtype))
            g = coupler.spread(f)  # the spreader's buffer: consumed before the next spread
            grid = s * 2.0 * g if grid is None else grid + s * 2.0 * g  # a new array: g is the reused buffer
        self.stokes_solves += con.mobility.n_products - n0 + 1
        grid *= self.drift_every * self.kT / self.delta
        return self.noise.stokes.velocity(grid)

    def __call__(self, X, dt, step):
        """(V, 3) backend array: noise velocity + drift at X for the step ``step`` of length dt. Leaves the mobility
        prepared at X."""
        be = self.constrained.backend
        self.constrained.dt, self.constrained.step = dt, step
        drift = None
        # a function of the step counter, so a resumed run applies the drift on the same steps
        if self.drift_every and step % self.drift_every == 0:
            n0 = self.constrained.mobility.n_products
            drift = self.drift_every * rfd_drift(self.constrained, be.asnumpy(X), self.kT, self.seed, step,
                                                 delta=self.delta)
            self.stokes_solves += self.constrained.mobility.n_products - n0
        self.constrained.mobility.prepare(X)
        u = self.constrained.mobility.coupler.interpolate(self.noise.velocity(dt, step))
        return u if drift is None else u + be.asarray(drift, dtype=u.dtype)


__all__ = ["ConstrainedMobility", "ThermalNoise", "ThermalVelocity", "noise_generator", "noise_mesh_warning",
           "mobility_matrix", "mobility_divergence", "rfd_drift"]
