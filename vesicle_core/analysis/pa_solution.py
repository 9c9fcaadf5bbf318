"""The perturbation analysis's solution after the reversal (eqs. 11-12): :class:`PASolution`, the dense ODE
output of :func:`vesicle_core.analysis.theory.solve` with the amplitudes, spectra and tension at any time."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..model.modes import a_l, gamma_l

__all__ = ["PASolution"]


@dataclass
class PASolution:
    """Solution of the PA after the reversal (internal representation; see :func:`solve`).

    ``u0``: initial amplitudes; ``ode``: scipy OdeSolution of (zeta, Re u_22) in s = t/tau; ``chi``: gamma_dot tau.
    Scalars at t_*: ``s_star`` (tau units), ``t_star`` (gamma_dot t), ``Delta_l_star``, ``u_absmax_star``,
    ``l_max_nontrivial``, ``l_star`` (eq. 31), ``l_peak``.
    """

    delta: float
    S: float
    chi: float
    l_max: int
    seed: int
    kT_over_kappa: float
    normalisation: str
    amplitudes: str
    thermal: str
    s_end: float
    u0: np.ndarray
    ode: object
    nfev: int
    s_star: float = float("nan")
    t_star: float = float("nan")
    Delta_l_star: np.ndarray = field(default=None, repr=False)
    u_absmax_star: np.ndarray = field(default=None, repr=False)
    l_max_nontrivial: int = -1
    l_star: float = float("nan")
    l_peak: float = float("nan")
    sigma_star: float = float("nan")
    mode_factor: np.ndarray = field(default=None, repr=False)  # r_l of grid_damping (None: the continuum)

    def __post_init__(self):
        L = self.l_max
        l = np.arange(L + 1)
        r = 1.0 if self.mode_factor is None else np.asarray(self.mode_factor, dtype=float)[: L + 1]
        self._G = gamma_l(l) * r
        self._A = a_l(l) * r
        free = np.abs(self.u0) ** 2
        free[2, L + 2] = free[2, L - 2] = 0.0
        free[:2] = 0.0
        D0 = free.sum(axis=-1)
        self._logD0 = np.where(D0 > 0, np.log(np.where(D0 > 0, D0, 1.0)), -np.inf)
        amax = np.sqrt(free.max(axis=-1))
        self._logamax0 = np.where(amax > 0, np.log(np.where(amax > 0, amax, 1.0)), -np.inf)
        self._w0 = float(np.imag(self.u0[2, L + 2]))
        self._Sr = -float(self.S)  # S(t) after the reversal

    # -- exact mode sums given (s, zeta, v) ------------------------------------------------------------------
    def _expo(self, s, zeta):
        """-Gamma_l s + A_l zeta for each l, shape (..., L+1)."""
        s = np.asarray(s, dtype=float)[..., None]
        zeta = np.asarray(zeta, dtype=float)[..., None]
        return -self._G * s + self._A * zeta

    def _sums(self, s, zeta, v):
        ex = self._expo(s, zeta)
        with np.errstate(invalid="ignore"):
            D = np.exp(np.minimum(self._logD0 + 2.0 * ex, 700.0))
        w = self._w0 * np.exp(np.minimum(ex[..., 2], 350.0))
        D[..., 2] += 2.0 * (np.asarray(v) ** 2 + w**2)
        return D, w

    def _sigma(self, s, zeta, v):
        D, _ = self._sums(s, zeta, v)
        Abar = (self._A * D).sum(axis=-1)
        Gbar = (self._G * D).sum(axis=-1)
        return (2.0 * self._Sr * np.asarray(v) - Gbar) / Abar

    def rhs(self, s, y):
        zeta, v = y
        sig = self._sigma(s, zeta, v)
        return [-sig, self._Sr - (self._A[2] * sig + self._G[2]) * v]

    # -- evaluation ---------------------------------------------------------------------------------------
    def state(self, s):
        """(zeta, Re u_22) at times s (tau units)."""
        y = self.ode(np.asarray(s, dtype=float))
        return y[0], y[1]

    def delta_l(self, s):
        """Delta_l at times s: (..., L+1)."""
        zeta, v = self.state(s)
        return self._sums(s, zeta, v)[0]

    def sigma(self, s):
        zeta, v = self.state(s)
        return self._sigma(s, zeta, v)

    def u(self, s):
        """Complex amplitudes at times s: (n, L+1, 2L+1)."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        zeta, v = self.state(s)
        ex = self._expo(s, zeta)
        E = np.exp(np.minimum(ex, 350.0))
        out = self.u0[None, :, :] * E[:, :, None]
        L = self.l_max
        w = self._w0 * E[:, 2]
        out[:, 2, L + 2] = v + 1j * w
        out[:, 2, L - 2] = v - 1j * w
        return out

    def u_absmax(self, s):
        """max_m |u_lm| at times s: (..., L+1)."""
        zeta, v = self.state(s)
        ex = self._expo(s, zeta)
        with np.errstate(invalid="ignore"):
            a = np.exp(np.minimum(self._logamax0 + ex, 350.0))
        w = self._w0 * np.exp(np.minimum(ex[..., 2], 350.0))
        a[..., 2] = np.maximum(a[..., 2], np.hypot(v, w))
        return a
