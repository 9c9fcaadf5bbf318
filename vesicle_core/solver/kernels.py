"""Regularised delta functions of the immersed boundary method, eqs. (26)-(27).

``phi`` is Peskin's 4-point kernel of eq. (27) (the paper's); ``delta3`` the tensor-product 3D delta of
eq. (26). ``stencil`` returns, for Lagrangian coordinates, the grid indices per axis that a kernel
touches and their weights; spreading (28) and interpolation (16, 29) share them so that the two
operations are exact adjoints. Three kernels (``KERNELS``, named in :mod:`vesicle_core.model.resolution`):

* ``"peskin4"``: Peskin's 4-point kernel, eq. (27). Moments: for any shift r,
  sum_j phi(r - j) = 1, sum_j (r - j) phi(r - j) = 0, sum_j phi(r - j)^2 = 3/8.
* ``"roma3"``: the 3-point kernel of Roma, Peskin & Berger, JCP 153 (1999): sum 1, first moment 0,
  sum of squares 1/2; the narrowest support (27 nodes in 3D against 64).
* ``"bao6"``: the 6-point kernel of Bao, Kaye & Peskin, JCP 316 (2016), K = 59/60 - sqrt(29)/20: three
  continuous derivatives, first three moments zero, and a much smaller translation-invariance error
  (216 nodes).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..model.resolution import DEFAULT_KERNEL, KERNELS
from ..xp import array_module


def phi(r, xp=None):
    """Peskin's 4-point kernel phi(r), eq. (27), elementwise; support |r| < 2."""
    xp = xp or array_module(r)
    r = xp.abs(xp.asarray(r, dtype=float) if xp is np else r)
    inner = 0.125 * (3.0 - 2.0 * r + xp.sqrt(xp.clip(1.0 + 4.0 * r - 4.0 * r * r, 0.0, None)))
    outer = 0.125 * (5.0 - 2.0 * r - xp.sqrt(xp.clip(-7.0 + 12.0 * r - 4.0 * r * r, 0.0, None)))
    return xp.where(r <= 1.0, inner, xp.where(r <= 2.0, outer, 0.0))


def delta3(r, h, xp=None):
    """The 3D regularised delta of eq. (26): prod_j phi(r_j / h) / h^3 for r of shape (..., 3)."""
    xp = xp or array_module(r)
    w = phi(r / h, xp)
    return w[..., 0] * w[..., 1] * w[..., 2] / h**3


_BAO_K = 59.0 / 60.0 - math.sqrt(29.0) / 20.0


def phi_roma3(r, xp=np):
    """Roma-Peskin-Berger 3-point kernel, elementwise; support |r| < 3/2."""
    r = xp.abs(r)
    inner = (1.0 + xp.sqrt(xp.clip(1.0 - 3.0 * r * r, 0.0, None))) / 3.0
    outer = (5.0 - 3.0 * r - xp.sqrt(xp.clip(1.0 - 3.0 * (1.0 - r) ** 2, 0.0, None))) / 6.0
    return xp.where(r <= 0.5, inner, xp.where(r <= 1.5, outer, 0.0))


def _bao6_weights(r, xp=np):
    """Bao-Kaye-Peskin 6-point weights at distances 2+r, 1+r, r, 1-r, 2-r, 3-r for r in [0, 1): (..., 6)."""
    K = _BAO_K
    r2, r3 = r * r, r * r * r
    beta = 9.0 / 4.0 - 1.5 * (K + r2) + (22.0 / 3.0 - 7.0 * K) * r - 7.0 / 3.0 * r3
    gamma = 0.25 * ((161.0 / 36.0 - 59.0 / 6.0 * K + 5.0 * K * K) * 0.5 * r2
                    + (-109.0 / 24.0 + 5.0 * K) / 3.0 * r2 * r2 + 5.0 / 18.0 * r3 * r3)
    disc = xp.clip(beta * beta - 112.0 * gamma, 0.0, None)
    pm3 = (-beta + xp.sqrt(disc)) / 56.0  # sign(3/2 - K) = +1
    pm2 = -3.0 * pm3 - 1.0 / 16.0 + (K + r2) / 8.0 + (3.0 * K - 1.0) * r / 12.0 + r3 / 12.0
    pm1 = 2.0 * pm3 + 0.25 + (4.0 - 3.0 * K) * r / 6.0 - r3 / 6.0
    p0 = 2.0 * pm3 + 5.0 / 8.0 - (K + r2) / 4.0
    pp1 = -3.0 * pm3 + 0.25 - (4.0 - 3.0 * K) * r / 6.0 + r3 / 6.0
    pp2 = pm3 - 1.0 / 16.0 + (K + r2) / 8.0 - (3.0 * K - 1.0) * r / 12.0 - r3 / 12.0
    return xp.stack([pp2, pp1, p0, pm1, pm2, pm3], axis=-1)


def phi_kernel(r, kernel=DEFAULT_KERNEL, xp=None):
    """The 1D kernel ``kernel`` at distances r (in h), elementwise."""
    xp = xp or array_module(r)
    if kernel == "peskin4":
        return phi(r, xp)
    if kernel == "roma3":
        return phi_roma3(xp.asarray(r, dtype=float) if xp is np else r, xp)
    if kernel == "bao6":
        r = xp.abs(xp.asarray(r, dtype=float) if xp is np else r)
        fl = xp.floor(r)
        w = _bao6_weights(r - fl, xp)  # w[..., 2] = phi(frac), w[..., 1] = phi(1 + frac), w[..., 0] = phi(2 + frac)
        out = xp.where(fl == 0, w[..., 2], xp.where(fl == 1, w[..., 1], xp.where(fl == 2, w[..., 0], 0.0)))
        return out
    raise ValueError(f"kernel must be one of {tuple(KERNELS)}, got {kernel!r}")


def stencil(X, h, N, origin=0.0, xp=None, kernel=DEFAULT_KERNEL):
    """Indices and weights of a kernel (default Peskin's 4-point) around Lagrangian points.

    Grid node ``m`` along an axis sits at ``origin + m h`` and the grid is periodic with N nodes.

    Parameters
    ----------
    X : array (M, 3)   Lagrangian positions.
    h : float          grid spacing.
    N : int            nodes per axis.
    origin : float     position of node 0 on every axis.

    Returns
    -------
    idx : int array (M, 3, w)  periodic grid indices per axis (w = KERNELS[kernel]).
    w   : array (M, 3, w)      phi((X - x_m)/h) per axis; the 3D weight is the product over axes
                               (dimensionless: the 1/h^3 of eq. (26) is left to the caller).
    """
    xp = xp or array_module(X)
    s = (X - origin) / h
    if kernel == "roma3":
        c = xp.floor(s + 0.5)  # nearest node
        d = s - c  # in [-1/2, 1/2)
        w = xp.stack([phi_roma3(1.0 + d, xp), phi_roma3(d, xp), phi_roma3(1.0 - d, xp)], axis=-1)
        j = c.astype(xp.int64)[..., None] - 1 + xp.arange(3, dtype=xp.int64)
        return j % N, w
    if kernel == "bao6":
        fl = xp.floor(s)
        w = _bao6_weights(s - fl, xp)
        j = fl.astype(xp.int64)[..., None] - 2 + xp.arange(6, dtype=xp.int64)
        return j % N, w
    if kernel != "peskin4":
        raise ValueError(f"kernel must be one of {tuple(KERNELS)}, got {kernel!r}")
    fl = xp.floor(s)
    r = s - fl  # in [0, 1): the point lies between nodes floor(s) and floor(s) + 1
    base = fl.astype(xp.int64) - 1
    # closed form of phi at the four distances 1 + r, r, 1 - r, 2 - r (one square root per axis
    # instead of evaluating eq. (27) piecewise 4 times; identical values, ~10x cheaper)
    q = xp.sqrt(xp.clip(1.0 + 4.0 * r * (1.0 - r), 0.0, None))
    a = 3.0 - 2.0 * r
    b = 1.0 + 2.0 * r
    w = xp.stack([a - q, a + q, b + q, b - q], axis=-1) * 0.125
    j = base[..., None] + xp.arange(4, dtype=xp.int64)  # (M, 3, 4)
    return j % N, w


# ---------------------------------------------------------------------------------------------------------------
# Window deconvolution (the sharpened coupling, ``coupling: sharp``)
#
# Spreading and interpolating with the same kernel filter the Stokes velocity twice: a marker sees
# G_hat(k) phi_hat(k)^2 F, with phi_hat the continuous Fourier transform of the 3D kernel (the tensor product of the
# 1D one). Spectral Ewald (Lindbo & Tornberg 2010) and positively split Ewald (Fiore et al. 2017) undo their window in
# Fourier space; here the same division is applied to the IB kernel, floored so that the near-zero tail of
# phi_hat^2 at the grid's Nyquist modes is not amplified without bound:
#
#     W(k) = 1 / max(phi_hat(k h)^2, floor),    phi_hat(k h) = prod_j phi_hat_1(k_j h)
#
# W is real, even and positive, so M = J L^{-1} xi W S stays symmetric positive semi-definite.

_HALF_WIDTH = {"peskin4": 2.0, "roma3": 1.5, "bao6": 3.0}  # support of phi(r) is |r| < half width (in h)


def _gauss_nodes(half_width, n=24):
    """Gauss-Legendre nodes and weights on [0, half_width], n per half cell: the kernels are smooth between
    multiples of 1/2 (their pieces join at integers or half integers), so the rule is exact to round-off."""
    x, w = np.polynomial.legendre.leggauss(n)
    edges = np.arange(0.0, half_width + 0.25, 0.5)
    a, b = edges[:-1, None], edges[1:, None]
    return (0.5 * (b - a) * x + 0.5 * (b + a)).ravel(), (0.5 * (b - a) * w).ravel()


def phi_hat(theta, kernel=DEFAULT_KERNEL):
    """Continuous Fourier transform of the 1D kernel, int phi(r) exp(-i theta r) dr, at theta = k h (radians per
    grid spacing). Real and even (the kernels are even); phi_hat(0) = 1 (the kernels sum to one). float64, host."""
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {tuple(KERNELS)}, got {kernel!r}")
    r, w = _gauss_nodes(_HALF_WIDTH[kernel])
    vals = phi_kernel(r, kernel, np) * w
    theta = np.asarray(theta, dtype=np.float64)
    return 2.0 * np.cos(theta[..., None] * r) @ vals


@functools.cache
def window_symbol_1d(N, kernel=DEFAULT_KERNEL):
    """phi_hat(2 pi m / N) for the FFT wave-number indices m = 0..N-1 (read-only float64; computed once per
    kernel and N)."""
    m = np.arange(N)
    out = phi_hat(2.0 * np.pi * np.minimum(m, N - m) / N, kernel)
    out.setflags(write=False)
    return out


def sharpening_symbol(N, kernel=DEFAULT_KERNEL, floor=0.01):
    """W = 1 / max(phi_hat^2, floor) on the real-FFT half spectrum (N, N, N // 2 + 1), float64 on the host.

    The factor the sharpened coupling applies to the spread force's spectrum (see above): 1 at k = 0, at most
    1 / floor. ``floor`` in (0, 1]; 1 gives W = 1, today's coupling."""
    if not 0.0 < floor <= 1.0:
        raise ValueError(f"sharp_floor must be in (0, 1], got {floor!r}")
    w1 = window_symbol_1d(N, kernel)
    wz = w1[: N // 2 + 1]
    p2 = (w1[:, None, None] * w1[None, :, None] * wz[None, None, :]) ** 2
    return 1.0 / np.maximum(p2, floor)
