"""Peskin's regularised delta function, eqs. (26)-(27).

``phi`` is the 4-point kernel of eq. (27); ``delta3`` the tensor-product 3D delta of eq. (26).
``stencil`` returns, for Lagrangian coordinates, the 4 grid indices per axis that the kernel
touches and their weights; spreading (28) and interpolation (16, 29) share them so that the
two operations are exact adjoints.

Moments (checked in tests): for any shift r,
    sum_j phi(r - j) = 1,  sum_j (r - j) phi(r - j) = 0,  sum_j phi(r - j)^2 = 3/8.
"""

from __future__ import annotations

import numpy as np


def _xp_of(a):
    try:  # CuPy arrays know their own module; NumPy is the default
        import cupy  # noqa: F401

        return cupy.get_array_module(a)
    except ImportError:
        return np


def phi(r, xp=None):
    """Peskin's 4-point kernel phi(r), eq. (27), elementwise; support |r| < 2."""
    xp = xp or _xp_of(r)
    r = xp.abs(xp.asarray(r, dtype=float) if xp is np else r)
    inner = 0.125 * (3.0 - 2.0 * r + xp.sqrt(xp.clip(1.0 + 4.0 * r - 4.0 * r * r, 0.0, None)))
    outer = 0.125 * (5.0 - 2.0 * r - xp.sqrt(xp.clip(-7.0 + 12.0 * r - 4.0 * r * r, 0.0, None)))
    return xp.where(r <= 1.0, inner, xp.where(r <= 2.0, outer, 0.0))


def delta3(r, h, xp=None):
    """The 3D regularised delta of eq. (26): prod_j phi(r_j / h) / h^3 for r of shape (..., 3)."""
    xp = xp or _xp_of(r)
    w = phi(r / h, xp)
    return w[..., 0] * w[..., 1] * w[..., 2] / h**3


def stencil(X, h, N, origin=0.0, xp=None):
    """Indices and weights of the 4-point kernel around Lagrangian points.

    Grid node ``m`` along an axis sits at ``origin + m h`` and the grid is periodic with N nodes.

    Parameters
    ----------
    X : array (M, 3)   Lagrangian positions.
    h : float          grid spacing.
    N : int            nodes per axis.
    origin : float     position of node 0 on every axis.

    Returns
    -------
    idx : int array (M, 3, 4)  periodic grid indices per axis.
    w   : array (M, 3, 4)      phi((X - x_m)/h) per axis; the 3D weight is the product over axes
                               (dimensionless: the 1/h^3 of eq. (26) is left to the caller).
    """
    xp = xp or _xp_of(X)
    s = (X - origin) / h
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
