"""Complex spherical harmonics Y_lm on points of the sphere: evaluation, projection of a real field and synthesis.

Conventions
-----------
* Lengths in R. Complex, orthonormal spherical harmonics with the Condon-Shortley phase, identical to
  ``scipy.special.sph_harm_y(l, m, theta, phi)`` (theta polar, phi azimuth)::

      Y_lm = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!) P_l^m(cos theta) exp(i m phi),   Y_{l,-m} = (-1)^m conj(Y_lm)

  They are evaluated by the standard stable three-term recurrence of the normalised associated Legendre
  functions (one pass per order m, nothing of size (n_modes x n_points) is ever stored): a whole snapshot
  (:func:`shape.analyze_snapshot`) takes ~0.06 s at l_max = 32 on 2*10^4 triangles, ~0.5 s at l_max = 64 on 5*10^4.
* Coefficient arrays have shape (..., l_max + 1, 2 l_max + 1): ``u[..., l, l_max + m]`` is u_lm; entries with
  |m| > l are 0 (datasets.py stores them as NaN). All analysed fields are real, so u_{l,-m} = (-1)^m conj(u_lm);
  only m >= 0 is computed and the rest filled by that symmetry.
* Projection uses conj(Y_lm): c_lm = sum_i f_i conj(Y_lm(theta_i, phi_i)) dOmega_i. Eq. (30) and (32) print Y_lm;
  for a real field that gives conj(c_lm) = (-1)^m c_{l,-m}, which has the same |c_lm| and Delta_l, but only the
  conjugated projection inverts eq. (10) (r = R [1 + sum c_lm Y_lm]).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError, MeshError, check_range


def _angles(rel):
    r = np.linalg.norm(rel, axis=1)
    if np.any(r == 0):
        raise MeshError("a quadrature node coincides with the centre; the surface is not star-shaped about it")
    theta = np.arccos(np.clip(rel[:, 2] / r, -1.0, 1.0))
    phi = np.arctan2(rel[:, 1], rel[:, 0])
    return r, theta, phi


def _legendre_rows(x, s, l_max):
    """Yield (m, P) for m = 0..l_max with P[l - m] = normalised P_lm(x) (incl. 1/sqrt(4 pi) and the
    Condon-Shortley phase), l = m..l_max, so that Y_lm = P[l - m] exp(i m phi)."""
    n = x.shape[0]
    pmm = np.full(n, 1.0 / math.sqrt(4.0 * math.pi))
    for m in range(l_max + 1):
        if m > 0:
            pmm = -math.sqrt((2.0 * m + 1.0) / (2.0 * m)) * s * pmm
        P = np.empty((l_max - m + 1, n))
        P[0] = pmm
        if m < l_max:
            P[1] = math.sqrt(2.0 * m + 3.0) * x * pmm
        for l in range(m + 2, l_max + 1):
            a = math.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b = math.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
            np.multiply(x, P[l - m - 1], out=P[l - m])
            P[l - m] -= b * P[l - m - 2]
            P[l - m] *= a
        yield m, P


def _check_lmax(l_max):
    return int(check_range("l_max", l_max, 0, 1000, integer=True))


def project(values, theta, phi, weights, l_max) -> np.ndarray:
    """Quadrature c_lm = sum_i values_i conj(Y_lm(theta_i, phi_i)) weights_i for real ``values``.

    values: (N,) or (k, N) real; returns complex (l_max+1, 2 l_max+1) or (k, l_max+1, 2 l_max+1), index [l, l_max + m],
    zero where |m| > l. Negative m follow from c_{l,-m} = (-1)^m conj(c_lm).
    """
    l_max = _check_lmax(l_max)
    vals = np.asarray(values)
    if np.iscomplexobj(vals):
        raise ConfigError("project() expects a real field (negative m are filled by the reality condition)")
    vals = vals.astype(float, copy=False)
    single = vals.ndim == 1
    vals = np.atleast_2d(vals)
    theta = np.asarray(theta, float).ravel()
    phi = np.asarray(phi, float).ravel()
    w = np.asarray(weights, float).ravel()
    if not (vals.shape[1] == theta.size == phi.size == w.size):
        raise ConfigError(f"values, theta, phi and weights must have the same length, got "
                          f"{vals.shape[1]}, {theta.size}, {phi.size}, {w.size}")
    k = vals.shape[0]
    out = np.zeros((k, l_max + 1, 2 * l_max + 1), dtype=complex)
    fw = vals * w[None, :]
    x, s = np.cos(theta), np.sin(theta)
    step = np.exp(-1j * phi)
    em = np.ones_like(step)  # exp(-i m phi), advanced by one complex product per order
    G = np.empty((2 * k, theta.size))
    for m, P in _legendre_rows(x, s, l_max):
        if m:
            em *= step
        np.multiply(fw, em.real, out=G[:k])
        np.multiply(fw, em.imag, out=G[k:])
        cg = P @ G.T  # (l_max - m + 1, 2k)
        c = cg[:, :k] + 1j * cg[:, k:]
        out[:, m:, l_max + m] = c.T
        if m:
            out[:, m:, l_max - m] = (-1) ** m * np.conj(c.T)
    return out[0] if single else out


def synthesize(coeffs, theta, phi) -> np.ndarray:
    """Real field sum_lm c_lm Y_lm(theta, phi) for coefficients of a real field (shape (l_max+1, 2 l_max+1),
    only m >= 0 are read); theta, phi any broadcastable shapes. Inverse of :func:`project` on a fine quadrature."""
    c = np.asarray(coeffs)
    l_max = c.shape[-2] - 1
    if c.shape[-1] != 2 * l_max + 1:
        raise ConfigError(f"coefficients must have shape (l_max+1, 2 l_max+1), got {c.shape}")
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    shape = theta.shape
    th, ph = theta.ravel(), phi.ravel()
    out = np.zeros(th.size)
    step = np.exp(1j * ph)
    em = np.ones_like(step)  # exp(i m phi), advanced by one complex product per order (as in project)
    for m, P in _legendre_rows(np.cos(th), np.sin(th), l_max):
        if m:
            em *= step
        cm = c[m:, l_max + m]
        # two real products: a complex vector times the real P would copy P to complex first
        val = np.real(cm) @ P * em.real - np.imag(cm) @ P * em.imag
        out += val if m == 0 else 2.0 * val
    return out.reshape(shape)


def fit_least_squares(values, theta, phi, weights, l_max, *, max_sweeps=8, rtol=1e-3):
    """Weighted least-squares coefficients up to l_max of a real field sampled at quadrature nodes.

    :func:`project` is exact only for fields the quadrature integrates exactly. On an irregular mesh its error
    aliases into every l and grows towards the mesh's resolvable l (on the quasi-uniform 5351-vertex ellipsoid,
    Delta_l ~ 1e-3 at l = 48 for a shape with none there). The least-squares coefficients minimise
    sum_i w_i (f_i - sum_lm c_lm Y_lm)^2, whose normal equations are project(f - synthesize(c)) = 0; they are
    solved by Richardson sweeps preconditioned by the quadrature itself, c <- c + project(f - synthesize(c)),
    starting from the quadrature. Sweeps stop when the weighted residual falls by less than ``rtol`` (relative)
    or after ``max_sweeps``; a sweep that raises the residual (the quadrature's Gram matrix has eigenvalues
    beyond 2 near the resolvable l) is discarded. Each sweep costs one synthesis and one projection.

    values (N,) or (k, N): returns what :func:`project` returns, plus the number of sweeps kept (the largest
    over the k fields).
    """
    vals = np.asarray(values, dtype=float)
    single = vals.ndim == 1
    vals = np.atleast_2d(vals)
    w = np.asarray(weights, float).ravel()
    c = project(vals, theta, phi, weights, l_max)
    kept = 0
    for j in range(vals.shape[0]):
        r = vals[j] - synthesize(c[j], theta, phi)
        rn = math.sqrt(float(np.sum(w * r * r)))
        for sweep in range(int(max_sweeps)):
            trial = c[j] + project(r, theta, phi, weights, l_max)
            r_trial = vals[j] - synthesize(trial, theta, phi)
            rn_trial = math.sqrt(float(np.sum(w * r_trial * r_trial)))
            if rn_trial > rn:
                break
            c[j], r, done = trial, r_trial, rn_trial > rn * (1.0 - rtol)
            rn = rn_trial
            kept = max(kept, sweep + 1)
            if done:
                break
    return (c[0] if single else c), kept


def ylm(l_max, theta, phi) -> np.ndarray:
    """All Y_lm at the given points, complex (l_max+1, 2 l_max+1, N) (zero where |m| > l).

    For checks and small point sets only (memory grows as l_max^2 N); the analysis never builds it."""
    l_max = _check_lmax(l_max)
    th = np.asarray(theta, float).ravel()
    ph = np.asarray(phi, float).ravel()
    out = np.zeros((l_max + 1, 2 * l_max + 1, th.size), dtype=complex)
    for m, P in _legendre_rows(np.cos(th), np.sin(th), l_max):
        y = P * np.exp(1j * m * ph)[None, :]
        out[m:, l_max + m] = y
        if m:
            out[m:, l_max - m] = (-1) ** m * np.conj(y)
    return out
