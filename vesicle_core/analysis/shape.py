"""The vesicle's shape beyond its spectrum: the fitted ellipsoid, the wrinkle amplitude A_p (Sec. V.C, eq. 32),
and everything Sec. V computes for one snapshot (:func:`analyze_snapshot`).

Wrinkle amplitude (Sec. V.C)
----------------------------
The surface is fitted by a general (rotated) ellipsoid (:func:`fit_ellipsoid`, area-weighted radial least squares
in :func:`analyze_snapshot`). A_p is the *radial* deviation of the membrane from that ellipsoid along the ray from
the ellipsoid's centre, positive outside: ``|X - c| - r_ell(direction)``, evaluated at the quadrature nodes; the
value of a triangle is its rule average (pn: 3/4 patch centre + 1/4 vertex mean).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError, check_choice
from ..geometry.surface import _as_mesh, pn_centers
from ..geometry.ylm import _check_lmax, project
from .harmonics import (
    NONTRIVIAL_THRESHOLD,
    RULES,
    _warn_resolution,
    characteristic_l,
    delta_l,
    fit_coefficients,
    l_max_nontrivial,
    quadrature,
    scale_factors,
)

AMPLITUDE_AT = ("triangles", "nodes", "vertices")

__all__ = [
    "fit_ellipsoid",
    "ellipsoid_radius",
    "wrinkle_amplitude",
    "mean_square_amplitude",
    "amplitude_spectrum",
    "analyze_snapshot",
]


def _rotvec_to_matrix(w):
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(w).as_matrix()


def _order_to_lab(axes, rot):
    """Permute principal axes so that column k of ``rot`` is the one most aligned with lab axis k; signs so the
    diagonal is >= 0 and det = +1."""
    from itertools import permutations

    best = max(permutations(range(3)), key=lambda p: sum(abs(rot[k, p[k]]) for k in range(3)))
    R = rot[:, list(best)].copy()
    a = np.asarray(axes)[list(best)].copy()
    for k in range(3):
        if R[k, k] < 0:
            R[:, k] *= -1
    if np.linalg.det(R) < 0:
        k = int(np.argmin(np.abs(np.diag(R))))
        R[:, k] *= -1
    return a, R


def ellipsoid_radius(directions, ellipsoid) -> np.ndarray:
    """Distance from the ellipsoid centre to its surface along unit ``directions`` (N, 3)."""
    _, axes, rot = ellipsoid
    d = np.asarray(directions, float) @ np.asarray(rot)  # body-frame components
    return 1.0 / np.sqrt(((d / np.asarray(axes)) ** 2).sum(axis=1))


def _radial_deviation(points, ellipsoid):
    c = np.asarray(ellipsoid[0], float)
    rel = np.asarray(points, float) - c
    r = np.linalg.norm(rel, axis=1)
    return r - ellipsoid_radius(rel / r[:, None], ellipsoid)


def _algebraic_ellipsoid(p):
    """Least-squares quadric x^T A x + 2 b^T x = 1 through the points (in normalised coordinates)."""
    o = p.mean(axis=0)
    s = np.sqrt(((p - o) ** 2).sum(axis=1).mean())
    q = (p - o) / s
    x, y, z = q.T
    D = np.stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z], axis=1)
    coef, *_ = np.linalg.lstsq(D, np.ones(len(q)), rcond=None)
    a, bb, cc, d, e, f_, g, h, i = coef
    A = np.array([[a, d, e], [d, bb, f_], [e, f_, cc]])
    bvec = np.array([g, h, i])
    try:
        cq = -np.linalg.solve(A, bvec)
    except np.linalg.LinAlgError:
        return None
    k = 1.0 + cq @ A @ cq
    lam, vec = np.linalg.eigh(A / k)
    if not np.all(lam > 0):
        return None
    return o + s * cq, s / np.sqrt(lam), vec


def fit_ellipsoid(points, weights=None, polish=True):
    """Least-squares ellipsoid through ``points`` (N >= 9, e.g. the mesh vertices).

    Algebraic fit of a general quadric (exact for points on an ellipsoid), then, with ``polish``, a
    Levenberg-Marquardt refinement of centre, semi-axes and orientation that minimises the (optionally weighted)
    squared *radial* deviations -- the quantity A_p measures. If the algebraic quadric is not an ellipsoid
    (strongly wrinkled shapes) the start is the centroid and the principal axes of the point cloud.

    Returns (center (3,), axes (3,), rotation (3, 3)): the surface is |diag(1/axes) rotation^T (x - center)| = 1;
    column k of ``rotation`` is the direction of semi-axis ``axes[k]``, ordered so that it is the principal axis
    closest to lab axis k (x, y, z), with non-negative diagonal and det = +1.
    """
    p = np.asarray(points, float)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 9:
        raise ConfigError(f"fit_ellipsoid needs at least 9 points of shape (N, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ConfigError("fit_ellipsoid: points contain NaN or Inf")
    start = _algebraic_ellipsoid(p)
    if start is None:
        o = p.mean(axis=0)
        cov = np.cov((p - o).T)
        lam, vec = np.linalg.eigh(cov)
        start = (o, np.sqrt(3.0 * np.clip(lam, 1e-30, None)), vec)  # shell of an ellipsoid: var = a^2 / 3
    c0, a0, R0 = start
    if np.linalg.det(R0) < 0:
        R0 = R0.copy()
        R0[:, 0] *= -1
    if polish:
        from scipy.optimize import least_squares

        sw = None if weights is None else np.sqrt(np.asarray(weights, float) / np.mean(weights))
        scale = float(np.mean(a0))

        def resid(x):
            R = R0 @ _rotvec_to_matrix(x[6:9])
            r = _radial_deviation(p, (c0 + scale * x[:3], a0 * np.exp(x[3:6]), R))
            return r if sw is None else r * sw

        x0 = np.zeros(9)
        if np.max(np.abs(resid(x0))) > 1e-12 * scale:
            sol = least_squares(resid, x0, method="lm", xtol=1e-12, ftol=1e-12, gtol=1e-12)
            x = sol.x
            c0, a0, R0 = c0 + scale * x[:3], a0 * np.exp(x[3:6]), R0 @ _rotvec_to_matrix(x[6:9])
    axes, rot = _order_to_lab(a0, R0)
    return np.asarray(c0, float), axes, rot


def wrinkle_amplitude(vertices, faces, ellipsoid, at="triangles", rule="pn") -> np.ndarray:
    """A_p: radial deviation of the membrane from the fitted ``ellipsoid`` (center, axes, rotation) along the ray
    from the ellipsoid centre, positive outside, in the units of the vertices.

    at="triangles" (default): one value per triangle, the average over the triangle with ``rule`` (pn: 3/4 at the
    PN patch centre + 1/4 vertex mean; vertex: vertex mean; centroid: at the flat centroid, which includes the
    facet's inward offset ~ edge^2 / 8R); "vertices": one value per vertex; "nodes": at the nodes of
    :func:`quadrature` with ``rule``.
    """
    check_choice("at", at, AMPLITUDE_AT)
    check_choice("rule", rule, RULES)
    v, f = _as_mesh(vertices, faces)
    if at == "vertices":
        return _radial_deviation(v, ellipsoid)
    if rule == "centroid":
        nodes = _radial_deviation(v[f].mean(axis=1), ellipsoid)
    elif rule == "vertex":
        nodes = _radial_deviation(v, ellipsoid)
    else:
        nodes = _radial_deviation(np.vstack([v, pn_centers(v, f)]), ellipsoid)
    if at == "nodes":
        return nodes
    if rule == "centroid":
        return nodes
    vmean = nodes[: len(v)][f].mean(axis=1)
    return vmean if rule == "vertex" else 0.75 * nodes[len(v):] + 0.25 * vmean


def mean_square_amplitude(A_p, areas) -> float:
    """A_p-bar = (1/A) sum_i A_p,i^2 A_i (Sec. V.C), A = sum_i A_i; units of A_p squared."""
    A_p = np.asarray(A_p, float)
    areas = np.asarray(areas, float)
    if A_p.shape != areas.shape:
        raise ConfigError(f"A_p and areas must have the same shape, got {A_p.shape} and {areas.shape}")
    return float((A_p**2 * areas).sum() / areas.sum())


def amplitude_spectrum(vertices, faces, ellipsoid, l_max, center=None, R=None, *, rule="pn",
                       weights="solid_angle"):
    """u~_lm of eq. (32), u~_lm = sum_i (A_p,i / R) conj(Y_lm(theta_i, phi_i)) dOmega_i (not scaled), and
    Delta~_l = sum_m |u~_lm|^2, with A_p the radial deviation from ``ellipsoid`` (center, axes, rotation) at the
    quadrature nodes of ``rule``. Centre default: the volume centroid; R default: the equivalent radius.
    Returns (u_tilde (l_max+1, 2 l_max+1) complex, Delta_tilde (l_max+1,)).
    """
    l_max = _check_lmax(l_max)
    v, f = _as_mesh(vertices, faces)
    q = quadrature(v, f, center=center, R=R, rule=rule, weights=weights)
    _warn_resolution(v, f, q.R, l_max)
    ut = project(_radial_deviation(q.points, ellipsoid) / q.R, q.theta, q.phi, q.weights, l_max)
    return ut, delta_l(ut)


def analyze_snapshot(vertices, faces, l_max, delta=None, R=None, *, rule="pn", weights="solid_angle",
                     threshold=NONTRIVIAL_THRESHOLD, warn=True, fit="quadrature") -> dict:
    """Everything Sec. V computes for one snapshot, with one pass of the harmonic recurrence for both fields.

    The ellipsoid is fitted to the vertices with area weights (vertex area = 1/3 of the adjacent triangles), so
    it minimises the area-weighted mean square of A_p. Returns a dict: u, Delta_l, l_max_nontrivial, l_star
    (eq. 31 up to l_max_nontrivial; NaN below 3), center, R, delta (used for scaling), delta_mesh (this
    snapshot's A/R^2 - 4 pi), ellipsoid (center, axes, rotation), A_p (per triangle, rule average), A_p_bar,
    u_tilde, Delta_tilde, areas. fit: how both fields' coefficients are read off the nodes
    (:func:`harmonics.fit_coefficients`).
    """
    l_max = _check_lmax(l_max)
    v, f = _as_mesh(vertices, faces)
    q = quadrature(v, f, R=R, rule=rule, weights=weights)
    if warn:
        _warn_resolution(v, f, q.R, l_max)
    delta_mesh = q.areas.sum() / q.R**2 - 4.0 * math.pi
    if delta is None:
        delta = delta_mesh
    vertex_area = np.bincount(f.ravel(), weights=np.repeat(q.areas / 3.0, 3), minlength=len(v))
    ell = fit_ellipsoid(v, weights=vertex_area)
    A_nodes = _radial_deviation(q.points, ell)
    A_tri = q.triangle_average(A_nodes)
    both = fit_coefficients(np.stack([(q.radius - q.R) / q.R, A_nodes / q.R]), q, l_max, fit)
    u = both[0] * scale_factors(l_max, delta)[:, None]
    ut = both[1]
    D = delta_l(u)
    lmn = l_max_nontrivial(u, threshold)
    return {
        "u": u,
        "Delta_l": D,
        "l_max_nontrivial": lmn,
        "l_star": characteristic_l(D, lmn) if lmn >= 3 else float("nan"),
        "center": q.center,
        "R": q.R,
        "delta": float(delta),
        "delta_mesh": float(delta_mesh),
        "ellipsoid": ell,
        "A_p": A_tri,
        "A_p_bar": mean_square_amplitude(A_tri, q.areas),
        "u_tilde": ut,
        "Delta_tilde": delta_l(ut),
        "areas": q.areas,
    }
