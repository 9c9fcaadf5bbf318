"""Euler characteristic of the excursion sets of a surface field, and its Gaussian-kinematic-formula mean.

The membrane's height about the fitted ellipsoid (A_p, Sec. V.C) is a field h on a closed triangulated surface,
given at the vertices and linear on each triangle. Its excursion set above level u is E_u = {h >= u}.

Counting (exact for the piecewise-linear field)
-----------------------------------------------
E_u deformation-retracts onto the subcomplex K_u spanned by the vertices with h >= u (each triangle's part of E_u
is convex and retracts onto the face spanned by its vertices above u), so::

    chi(E_u) = V_u - E_u + F_u

counts the vertices with h >= u, the edges with both ends >= u and the triangles with all three >= u. No
interpolation, no image, no tolerance.

Duality: on a closed surface every simplex with vertices on both sides of u is an edge or a triangle; each such
triangle has exactly two such edges and each such edge lies in two such triangles, so they cancel in V - E + F and::

    chi({h >= u}) + chi({h < u}) = chi(surface) = 2   (genus 0), exactly, for every u.

Gaussian kinematic formula (Adler & Taylor 2007, Random Fields and Geometry, Thm. 12.4.1 and Sec. 13)
----------------------------------------------------------------------------------------------------
For a smooth, isotropic, zero-mean, unit-variance Gaussian field on the unit sphere S^2,
E chi(E_u) = sum_j L_j(S^2) rho_j(u). The field's metric is lambda_2 times the round one, where lambda_2 =
Var(dh/ds) along any unit tangent; so L_0 = chi(S^2) = 2, L_1 = 0 (no boundary) and L_2 = lambda_2 4 pi. With
rho_0 = Psi(u) = 1 - Phi(u) and rho_2 = u exp(-u^2/2) / (2 pi)^(3/2)::

    E chi(u) = 2 Psi(u) + 4 pi lambda_2 u exp(-u^2 / 2) / (2 pi)^(3/2).

For a field of one degree l (random Y_lm coefficients), E|grad h|^2 = l (l + 1) E h^2 (the eigenvalue of the
Laplace-Beltrami operator), shared by two tangent directions: lambda_2 = l (l + 1) / 2. For a spectrum C_l:
lambda_2 = sum_l (2l+1) C_l l (l+1) / 2 / sum_l (2l+1) C_l. Tests: tests/analysis/test_excursion.py.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr

from ..errors import ConfigError
from ..geometry.mesh import unique_edges

__all__ = ["euler_characteristic", "euler_characteristic_below", "euler_curve", "gkf_expected_euler",
           "lambda2_single_degree"]


def _check(faces, values):
    f = np.asarray(faces)
    h = np.asarray(values, float)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ConfigError(f"faces must have shape (F, 3), got {f.shape}")
    if h.ndim not in (1, 2) or h.shape[-1] <= f.max():
        raise ConfigError(f"values must hold one entry per vertex (at least {f.max() + 1}) along the last axis, "
                          f"got shape {h.shape}")
    if not np.all(np.isfinite(h)):
        raise ConfigError("values contain NaN or Inf")
    return f.astype(np.int64), h


def _count(inside, faces, edges):
    """V - E + F of the subcomplex spanned by the vertices where ``inside`` (..., V) is True."""
    n_v = inside.sum(axis=-1)
    n_e = (inside[..., edges[:, 0]] & inside[..., edges[:, 1]]).sum(axis=-1)
    n_f = (inside[..., faces[:, 0]] & inside[..., faces[:, 1]] & inside[..., faces[:, 2]]).sum(axis=-1)
    return (n_v - n_e + n_f).astype(np.int64)


def _levels_count(faces, values, levels, above):
    f, h = _check(faces, values)
    u = np.atleast_1d(np.asarray(levels, float))
    hh = h[..., None, :]
    inside = hh >= u[:, None] if above else hh < u[:, None]
    out = _count(inside, f, unique_edges(f))
    return out if np.ndim(levels) else out[..., 0]


def euler_characteristic(faces, values, levels) -> np.ndarray:
    """chi({h >= u}) for each level u in ``levels`` (scalar or array), h = ``values`` per vertex (V,), or a stack
    of fields (n, V) (then the result has shape (n, len(levels)))."""
    return _levels_count(faces, values, levels, True)


def euler_characteristic_below(faces, values, levels) -> np.ndarray:
    """chi({h < u}): the complement's count, independent of :func:`euler_characteristic` (for the duality test)."""
    return _levels_count(faces, values, levels, False)


def euler_curve(faces, values, levels_in_sd) -> np.ndarray:
    """chi({h >= u sigma}) at levels in units of the field's rms about its mean, sigma (area-agnostic, per vertex);
    the levels are taken about the mean, so the curve does not depend on an additive constant or on the scale of h.
    """
    _, h = _check(faces, values)
    if h.ndim != 1:
        raise ConfigError(f"euler_curve takes one field (V,), got shape {h.shape}")
    h = h - h.mean()
    sd = h.std()
    if sd == 0:
        raise ConfigError("values are constant: the Euler curve needs a field that varies")
    return euler_characteristic(faces, h / sd, levels_in_sd)


def lambda2_single_degree(l) -> float:
    """Second spectral moment lambda_2 = l (l + 1) / 2 of an isotropic field of degree l on the unit sphere."""
    if l < 0:
        raise ConfigError(f"degree l must be >= 0, got {l}")
    return 0.5 * l * (l + 1)


def gkf_expected_euler(u, lambda2, area=4.0 * math.pi, chi_surface=2) -> np.ndarray:
    """E chi({h >= u}) = chi_surface Psi(u) + area lambda_2 u exp(-u^2/2) / (2 pi)^(3/2) for a unit-variance
    isotropic Gaussian field on a closed surface of ``area`` (unit sphere: 4 pi, chi 2); see the module docstring."""
    if lambda2 < 0:
        raise ConfigError(f"lambda2 must be >= 0, got {lambda2}")
    u = np.asarray(u, float)
    return chi_surface * ndtr(-u) + area * lambda2 * u * np.exp(-0.5 * u * u) / (2.0 * math.pi) ** 1.5
