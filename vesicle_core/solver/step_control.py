r"""Step-size control from an error estimate (run parameter ``step_control: error``), kept apart from the update.

Two pieces, neither of which takes a step:

* :class:`WrinkleNorm`: the size of a step's error estimate against a tolerance on the wrinkle amplitudes. The
  estimate e (a displacement per vertex, :mod:`vesicle_core.solver.embedded_midpoint`) is reduced to its normal part
  e_n = n . e (the tangential part moves lipid along the surface, not the shape) and split by a weighted least-squares
  projection into the band l <= ``L_LOW`` (the vesicle's shape: the flow's l = 2 strain and what it drives) and the
  rest (the wrinkles, l_* = 9-32 in the default job, and any mesh-scale modes). Each band is measured by its
  area-weighted rms and divided by ``atol + rtol x`` the same band's amplitude in the shape itself, the rms of the
  radial function r = abs(X - centroid) over the vertices in that band (the l = 0 part left out):

      err = max( rms(e_n high) / (atol + rtol W),  rms(e_n low) / (atol + rtol D) ),
      W = rms(r high), D = rms(r low, l >= 1)

  Why these choices. rms, not max: l_* and t_* come from the power spectrum Delta_l, a sum of squared amplitudes, so
  by Parseval the rms of the high band's error is the square root of the summed error powers the spectrum sees; a max
  would follow single-vertex mesh noise. The split: the wrinkles grow exponentially from a seed ~1e-3 of the shape's
  deformation, so a tolerance relative to the whole displacement (one band) would let their growth rates go wrong
  while they are small, which is when l_* is selected (an error in a growth rate multiplies the amplitude at t_*).
  Relative to their own amplitude W, the Euler error estimate of a mode growing at rate r is (r dt)^2 / 2 of it, so
  ``rtol`` fixes r dt, the e-folds per step, from the modes actually there, not from linear theory's fastest rate.
  The low band is the flow's: its strain per step is held to the same relative accuracy of the deformation D.
  ``atol`` = ``ATOL_H`` rtol h keeps the norm finite on a shape without wrinkles (a seed of mesh noise).
  The band edge, polynomials of degree <= L_LOW in the reference mesh's directions (the same span as the spherical
  harmonics l <= L_LOW on the unit sphere), is fixed on the reference mesh: a projection matrix of V x ~25.

* :class:`StepController`: scipy.integrate's RK23 rules for the next step from ``err`` (error estimate of order 1,
  local error ~ dt^2, so the exponent is -1/2): accept when err <= 1; the next step is
  dt min(MAX_FACTOR, SAFETY err^(-1/2)), not longer than dt after a rejection in the same step; a rejected step is
  retried at dt max(MIN_FACTOR, SAFETY err^(-1/2)).
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.surface import dot_rows

# scipy.integrate.RK23's constants (scipy/integrate/_ivp/rk.py)
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
#: highest l of the shape band: the ellipsoid's l = 2 and 4, the flow's strain; the wrinkles start at l ~ 5
L_LOW = 4
#: atol in grid spacings, per unit of rtol: a wrinkle amplitude of 1% of h counts as none
ATOL_H = 1e-2


class StepController:
    """The next step from the error of the last one (module docstring); no state beyond the constants."""

    def __init__(self, order: int = 1):
        self.exponent = -1.0 / (order + 1)  # the estimate is of the order-`order` solution: local error dt^(order+1)

    def accept_factor(self, err: float, rejected_before: bool) -> float:
        """Factor on the accepted step for the next one."""
        factor = MAX_FACTOR if err == 0 else min(MAX_FACTOR, SAFETY * err ** self.exponent)
        return min(1.0, factor) if rejected_before else factor

    def reject_factor(self, err: float) -> float:
        """Factor on a rejected step (err > 1) for its retry."""
        return max(MIN_FACTOR, SAFETY * err ** self.exponent)


class WrinkleNorm:
    """err of a step's error estimate (module docstring), with the shape/wrinkle band split fixed on ``X0``."""

    def __init__(self, X0, weights, h: float, rtol: float, l_low: int = L_LOW):
        X0 = np.asarray(X0, dtype=float)
        u = X0 - X0.mean(axis=0)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        # monomials x^a y^b z^c, a + b + c <= l_low, on the unit directions: the span of Y_lm, l <= l_low
        cols = [u[:, 0] ** a * u[:, 1] ** b * u[:, 2] ** c for a in range(l_low + 1) for b in range(l_low + 1 - a)
                for c in range(l_low + 1 - a - b)]
        w = np.asarray(weights, dtype=float)
        self.w = w / w.sum()
        M = np.stack(cols, axis=1) * np.sqrt(self.w)[:, None]
        U, s, _ = np.linalg.svd(M, full_matrices=False)
        self.Q = U[:, s > 1e-10 * s[0]]  # orthonormal in the weighted inner product (after the sqrt(w) scaling)
        self.sw = np.sqrt(self.w)
        const = self.sw / np.linalg.norm(self.sw)  # the l = 0 direction, in the same scaling
        self.const = const
        self.rtol = float(rtol)
        self.atol = ATOL_H * float(rtol) * float(h)

    def bands(self, f, mean: bool = True) -> tuple[float, float]:
        """Weighted rms of a vertex field's low band (l <= l_low; without its mean, l = 0, unless ``mean``) and of
        its high band."""
        g = self.sw * np.asarray(f, dtype=float)
        low = self.Q @ (self.Q.T @ g)
        high = g - low
        if not mean:
            low = low - self.const * (self.const @ low)
        return float(np.linalg.norm(low)), float(np.linalg.norm(high))

    def amplitudes(self, X) -> tuple[float, float]:
        """(D, W): the shape's deformation and its wrinkles, rms of the radial function's two bands [R]."""
        X = np.asarray(X, dtype=float)
        return self.bands(np.linalg.norm(X - X.mean(axis=0), axis=1), mean=False)

    def __call__(self, X, normals, e) -> float:
        """err of the displacement error estimate ``e`` (V, 3) of a step from X (normals (V, 3), unit)."""
        en = dot_rows(np.asarray(normals, dtype=float), np.asarray(e, dtype=float))
        e_low, e_high = self.bands(en)
        D, W = self.amplitudes(X)
        err = max(e_high / (self.atol + self.rtol * W), e_low / (self.atol + self.rtol * D))
        return err if math.isfinite(err) else math.inf
