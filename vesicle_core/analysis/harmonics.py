"""Spherical-harmonic analysis of a triangulated vesicle (Sec. III eq. 10, Sec. V eqs. 30-32).

Conventions of the basis (Y_lm, coefficient layout, conjugated projection): :mod:`vesicle_core.geometry.ylm`.
The surface quantities (areas, volume centroid, solid angles, normals, PN patch centres):
:mod:`vesicle_core.geometry.surface`.

Scaled amplitudes (eq. 30)
--------------------------
``u_lm = sqrt((l-1)(l+2)/Delta) c_lm`` with ``c_lm = int (r - R)/R conj(Y_lm) dOmega``. For l = 0, 1 the
factor is 0 or undefined, so **u_00 and u_1m hold the unscaled c_lm** (u_00 ~ 0 when R is the equivalent radius,
u_1m ~ 0 when the centre is the volume centroid). With this normalisation a quasi-spherical shape has
sum_{l>=2, m} |u_lm|^2 = 2 (Delta = sum_{l>=2} (l-1)(l+2)/2 sum_m |c_lm|^2 to second order in the shape
perturbation; see :func:`excess_area`).

Quadrature (documented choices; measured in tests/analysis/test_harmonics.py)
--------------------------------------------------------------------
* Centre X_C: the *volume* centroid of the enclosed solid (divergence theorem). It does not depend on how
  densely the membrane is meshed, and it makes the l = 1 coefficients vanish to first order.
* Weights, ``weights=``:
  ``"solid_angle"`` (default): the exact solid angle dOmega_i that triangle i subtends at X_C (Van Oosterom &
  Strackee, signed), so the weights sum to exactly 4 pi on any closed surface around X_C.
  ``"paper"``: dOmega_i = A_i / r_i^2 as printed under eq. (30) (r_i: distance of the centroid). That is the
  solid angle only for facets perpendicular to the ray; tilted facets (elongated shapes, wrinkles) are
  over-weighted by ~1 / cos(tilt), and the weights no longer sum to 4 pi (+1.4 % on the meshed 1:0.8:1
  ellipsoid, +12 % at Delta = 1).
* Rule inside each triangle, ``rule=`` (each triangle's dOmega_i is shared among the rule's nodes):
  ``"pn"`` (default): four-point rule, 3/4 of dOmega_i at the centre of the curved PN ("point-normal",
  Vlachos et al. 2001) cubic patch through the triangle's vertices and vertex normals, 1/12 at each vertex.
  The rule is exact for quadratic integrands on the patch, and both the vertices and the patch centre lie on
  the smooth surface through the membrane points, so neither the facet offset nor the mesh pattern leaks much.
  ``"vertex"``: three-point rule at the vertices (the Lagrangian membrane points: exact r and angles). No
  amplitude bias, but its O(h^2) error follows the triangle-size pattern and aliases into high l.
  ``"centroid"``: eq. (30) literally: one point at the flat triangle's centroid. The facet lies inside the
  smooth surface by ~ edge^2 / 8R; the one-point rule smooths amplitudes by ~ (1 - h^2 l(l+1) / 12).
  Level-5 icosphere, measured (tests): recovered amplitude error / largest leakage (relative to the injected
  amplitude) for an l = 10 mode: pn 6e-5 / 2e-5, vertex 2e-5 / 1.3e-3, centroid 1.6e-2 / 4e-3; at l = 30:
  pn 1.5e-2, vertex 1e-3, centroid 1.1e-1. On the smooth 1:0.8:1 ellipsoid (level 5, l_max = 64) the spurious
  Delta_l at l = 40 is 1e-6 (pn), 5e-3 (vertex), 5e-4 (centroid), so only pn gives the l_* of a smooth
  ellipsoid as ~ 4 (its own l = 4 content), where vertex / centroid give 9 / 5.

Wrinkle amplitude (Sec. V.C)
----------------------------
The surface is fitted by a general (rotated) ellipsoid (:func:`fit_ellipsoid`, area-weighted radial least squares
in :func:`analyze_snapshot`). A_p is the *radial* deviation of the membrane from that ellipsoid along the ray from
the ellipsoid's centre, positive outside: ``|X - c| - r_ell(direction)``, evaluated at the quadrature nodes; the
value of a triangle is its rule average (pn: 3/4 patch centre + 1/4 vertex mean).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_choice, check_range
from ..geometry.surface import (
    _as_mesh,
    _equivalent_radius,
    dot,
    face_area_vectors,
    pn_centers,
    resolvable_l_max,
    solid_angles,
    volume_centroid,
)
from ..geometry.ylm import _angles, _check_lmax, project, synthesize

__all__ = [
    "ResolutionWarning",
    "Quadrature",
    "quadrature",
    "field_spectrum",
    "resolved_field",
    "scale_factors",
    "decompose",
    "delta_l",
    "excess_area",
    "t_star",
    "t_star_index",
    "l_max_nontrivial",
    "characteristic_l",
    "fit_ellipsoid",
    "ellipsoid_radius",
    "wrinkle_amplitude",
    "mean_square_amplitude",
    "amplitude_spectrum",
    "analyze_snapshot",
]

WEIGHTS = ("solid_angle", "paper")
RULES = ("pn", "vertex", "centroid")
AMPLITUDE_AT = ("triangles", "nodes", "vertices")
#: |u_lm| above which a mode counts as nontrivial: the l_max of Sec. V.A is the largest such l at t_*
NONTRIVIAL_THRESHOLD = 1e-5
METHODS = ("eq31", "peak")  # of characteristic_l: eq. (31) or the dominant mode (Sec. V.A)


class ResolutionWarning(UserWarning):
    """l_max asks for wavelengths the mesh cannot represent (more than about one mode per two edges)."""


@dataclass
class Quadrature:
    """Quadrature nodes of eq. (30) on one snapshot.

    points (N, 3): node positions (absolute); theta, phi, radius: their direction and distance seen from
    ``center``; weights: their share of the solid angle; ``R`` the reference radius; ``areas`` the triangle areas.
    Nodes: rule "pn" -> the V vertices, then the F patch centres; "vertex" -> the vertices; "centroid" -> the F
    flat centroids. :meth:`triangle_average` turns node values into one value per triangle with the rule.
    """

    rule: str
    weights_kind: str
    center: np.ndarray
    R: float
    points: np.ndarray
    theta: np.ndarray
    phi: np.ndarray
    radius: np.ndarray
    weights: np.ndarray
    areas: np.ndarray
    faces: np.ndarray
    n_vertices: int

    @property
    def n_nodes(self) -> int:
        return int(self.theta.size)

    def triangle_average(self, node_values) -> np.ndarray:
        x = np.asarray(node_values)
        if self.rule == "centroid":
            return x
        vmean = x[: self.n_vertices][self.faces].mean(axis=1)
        if self.rule == "vertex":
            return vmean
        return 0.75 * x[self.n_vertices:] + 0.25 * vmean


def quadrature(vertices, faces, center=None, R=None, rule="pn", weights="solid_angle") -> Quadrature:
    """Quadrature of eq. (30) on a closed triangulated surface (see the module docstring for the choices).

    center: default the volume centroid; R: default the equivalent radius (sphere of equal volume).
    """
    check_choice("weights", weights, WEIGHTS)
    check_choice("rule", rule, RULES)
    v, f = _as_mesh(vertices, faces)
    c0 = volume_centroid(v, f) if center is None else np.asarray(center, dtype=float).reshape(3)
    if R is None:
        R = _equivalent_radius(v, f)
    check_range("R", R, 0.0, None, lo_open=True)
    rel = v - c0
    a, b, c = rel[f[:, 0]], rel[f[:, 1]], rel[f[:, 2]]
    areas = np.linalg.norm(face_area_vectors(rel, f), axis=1)
    cen = (a + b + c) / 3.0
    if weights == "solid_angle":
        w_tri = solid_angles(v, f, c0)
    else:
        w_tri = areas / dot(cen.T, cen.T)

    def to_vertices(w):
        return np.bincount(f.ravel(), weights=np.repeat(w / 3.0, 3), minlength=len(v))

    if rule == "centroid":
        pts = cen
        w = w_tri
    elif rule == "vertex":
        pts = rel
        w = to_vertices(w_tri)
    else:
        pts = np.vstack([rel, pn_centers(v, f) - c0])
        w = np.concatenate([to_vertices(0.25 * w_tri), 0.75 * w_tri])
    r, theta, phi = _angles(pts)
    return Quadrature(rule, weights, c0, float(R), pts + c0, theta, phi, r, w, areas, f, len(v))


def scale_factors(l_max, delta) -> np.ndarray:
    """Factor sqrt((l-1)(l+2)/Delta) of eq. (30) per l, shape (l_max+1,); 1 for l = 0, 1 (stored unscaled)."""
    l_max = _check_lmax(l_max)
    check_range("delta", delta, 0.0, None, lo_open=True)
    l = np.arange(l_max + 1, dtype=float)
    f = np.sqrt(np.clip((l - 1.0) * (l + 2.0), 0.0, None) / float(delta))
    f[:2] = 1.0
    return f


def _warn_resolution(v, f, R, l_max, stacklevel=3):
    l_res = resolvable_l_max(v, f, R)
    if l_max > l_res:
        warnings.warn(
            f"l_max = {l_max} exceeds what this mesh resolves (pi / mean angular edge = {l_res}); "
            "modes above it are aliased mesh noise",
            ResolutionWarning,
            stacklevel=stacklevel,
        )
    return l_res


def decompose(vertices, faces, l_max, delta=None, R=None, center=None, *, rule="pn",
              weights="solid_angle") -> np.ndarray:
    """Scaled amplitudes u_lm of eq. (30), complex (l_max+1, 2 l_max+1), index [l, l_max + m].

    delta: the vesicle's excess area Delta of the scale factor sqrt((l-1)(l+2)/Delta) (default: this mesh's own
    A/R^2 - 4 pi). R: reference radius (default: equivalent radius from the enclosed volume). center: default the
    volume centroid. rule / weights: see the module docstring. l = 0, 1 entries are the unscaled coefficients.
    Warns (ResolutionWarning) if l_max exceeds :func:`resolvable_l_max`.
    """
    l_max = _check_lmax(l_max)
    v, f = _as_mesh(vertices, faces)
    q = quadrature(v, f, center=center, R=R, rule=rule, weights=weights)
    _warn_resolution(v, f, q.R, l_max)
    if delta is None:
        delta = q.areas.sum() / q.R**2 - 4.0 * math.pi
    c = project((q.radius - q.R) / q.R, q.theta, q.phi, q.weights, l_max)
    return c * scale_factors(l_max, delta)[:, None]


def delta_l(u) -> np.ndarray:
    """Delta_l = sum_m |u_lm|^2 over the last axis, shape (..., l_max+1); NaN entries (|m| > l in datasets) are
    ignored. The one implementation for the simulation spectra and the PA (``theory.delta_l`` is this function)."""
    u = np.asarray(u)
    return np.nansum(np.abs(u) ** 2, axis=-1)


def excess_area(u, delta) -> np.ndarray:
    """Excess area carried by the modes l >= 2 of scaled amplitudes u (second order in the shape perturbation):
    Delta_u = (Delta / 2) sum_{l>=2, m} |u_lm|^2 = sum_{l>=2} (l-1)(l+2)/2 sum_m |c_lm|^2."""
    return 0.5 * float(delta) * delta_l(u)[..., 2:].sum(axis=-1)


def t_star_index(time, Delta_2) -> int:
    """Index of min Delta_2 over time >= 0 (after the flow reversal); -1 if there is no finite value there."""
    t = np.asarray(time, float)
    d = np.asarray(Delta_2, float)
    if t.shape != d.shape or t.ndim != 1:
        raise ConfigError(f"time and Delta_2 must be 1-D of equal length, got {t.shape} and {d.shape}")
    ok = (t >= 0) & np.isfinite(d)
    if not ok.any():
        return -1
    idx = np.flatnonzero(ok)
    return int(idx[np.argmin(d[idx])])


def t_star(time, Delta_2) -> float:
    """t_*: the time >= 0 at which Delta_2 is smallest (Sec. V.A); NaN if no snapshot after the reversal."""
    i = t_star_index(time, Delta_2)
    return float(np.asarray(time, float)[i]) if i >= 0 else float("nan")


def l_max_nontrivial(u, threshold=NONTRIVIAL_THRESHOLD):
    """Largest l with some |u_lm| > threshold (Sec. V.A); -1 if none. Works on (..., l, m) arrays (an m axis of
    length 1 takes max_m |u_lm|). The one implementation for the simulation spectra and the PA
    (``theory.nontrivial_l_max`` is this function)."""
    a = np.abs(np.nan_to_num(np.asarray(u), nan=0.0))
    big = (a > threshold).any(axis=-1)  # (..., l)
    L = big.shape[-1]
    last = L - 1 - np.argmax(big[..., ::-1], axis=-1)
    out = np.where(big.any(axis=-1), last, -1)
    return int(out) if np.ndim(out) == 0 else out.astype(int)


def characteristic_l(Delta_l, l_max=None, *, l_min=3, method="eq31"):
    """Characteristic wrinkle mode l_* from Delta_l = sum_m |u_lm|^2 (arrays (..., L) indexed by l from 0).

    ``method="eq31"`` (default), eq. (31)::

        l_*^2 = sum_{l_min<=l<=l_max} l^2/(l^2+l-2) Delta_l / sum_{l_min<=l<=l_max} 1/(l^2+l-2) Delta_l

    (the rms l of the unscaled spectrum |c_lm|^2 = Delta |u_lm|^2/((l-1)(l+2))); NaN where the denominator
    vanishes. ``method="peak"``: argmax_{l_min<=l<=l_max} Delta_l as a float (NaN if all zero), the definition
    at the start of Sec. V.A. l_max: int or array broadcastable to the leading shape (default L-1; pass
    :func:`nontrivial_l_max` at t_* to follow the paper). NaN entries count as 0. The same function serves the
    PA and the simulation spectra, so their l_* are computed identically.
    """
    check_choice("method", method, METHODS)
    check_range("l_min", l_min, 2, None, integer=True)
    D = np.nan_to_num(np.asarray(Delta_l, dtype=float), nan=0.0)
    if D.ndim == 0:
        raise ConfigError("Delta_l must be an array indexed by l")
    L = D.shape[-1]
    l = np.arange(L, dtype=float)
    lm = np.asarray(L - 1 if l_max is None else l_max)
    mask = (l >= l_min) & (l <= lm[..., None])
    if method == "peak":
        Dm = np.where(mask, D, -np.inf)
        idx = np.argmax(Dm, axis=-1)
        best = np.take_along_axis(Dm, idx[..., None], axis=-1)[..., 0]
        out = np.where(best > 0, idx.astype(float), np.nan)
    else:
        g = np.where(l >= 2, (l - 1) * (l + 2), 1.0)
        num = np.where(mask, l**2 / g * D, 0.0).sum(axis=-1)
        den = np.where(mask, D / g, 0.0).sum(axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            out = np.where(den > 0, np.sqrt(num / np.where(den > 0, den, 1.0)), np.nan)
    return float(out) if np.ndim(out) == 0 else out


# --------------------------------------------------------------------------- ellipsoid fit and wrinkles
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


def field_spectrum(vertices, faces, values, l_max, center=None, R=None, *, weights="solid_angle") -> np.ndarray:
    """Coefficients c_lm = sum_i values_i conj(Y_lm) dOmega_i of any real field given per vertex (shape (V,),
    vertex rule) or per triangle (shape (F,), centroid rule), e.g. the local tension. V != F on a closed
    genus-0 mesh, so the shape decides."""
    l_max = _check_lmax(l_max)
    v, f = _as_mesh(vertices, faces)
    x = np.asarray(values, float)
    if x.shape == (len(v),):
        rule = "vertex"
    elif x.shape == (len(f),):
        rule = "centroid"
    else:
        raise ConfigError(f"values must hold one entry per vertex ({len(v)}) or per triangle ({len(f)}), "
                          f"got shape {x.shape}")
    q = quadrature(v, f, center=center, R=R, rule=rule, weights=weights)
    _warn_resolution(v, f, q.R, l_max)
    return project(x, q.theta, q.phi, q.weights, l_max)


def resolved_field(vertices, faces, values, l_max=None, center=None, R=None) -> np.ndarray:
    """A surface field's spherical-harmonic expansion up to ``l_max``, evaluated at the vertices, (V,).

    ``values``: per vertex or per triangle (:func:`field_spectrum`). Default l_max: half the mesh's resolvable l
    (:func:`resolvable_l_max`), four edges per wavelength. For the inextensible scheme's per-triangle tension this
    is the part the grid resolves: most of its variance (75-93% in the S = 2224 runs at N = 64 and 128) lies
    beyond the resolvable l, in nearly force-free patterns that alternate between neighbouring triangles
    (docs/solver.md, "Tension noise"); the vertex average keeps part of them. The surface must be star-shaped
    about the centre (default: the volume centroid).
    """
    v, f = _as_mesh(vertices, faces)
    if l_max is None:
        l_max = max(1, resolvable_l_max(v, f, R) // 2)
    c0 = volume_centroid(v, f) if center is None else np.asarray(center, dtype=float).reshape(3)
    c = field_spectrum(v, f, values, l_max, center=c0, R=R)
    _, theta, phi = _angles(v - c0)
    return synthesize(c, theta, phi)


def analyze_snapshot(vertices, faces, l_max, delta=None, R=None, *, rule="pn", weights="solid_angle",
                     threshold=NONTRIVIAL_THRESHOLD, warn=True) -> dict:
    """Everything Sec. V computes for one snapshot, with one pass of the harmonic recurrence for both fields.

    The ellipsoid is fitted to the vertices with area weights (vertex area = 1/3 of the adjacent triangles), so
    it minimises the area-weighted mean square of A_p. Returns a dict: u, Delta_l, l_max_nontrivial, l_star
    (eq. 31 up to l_max_nontrivial; NaN below 3), center, R, delta (used for scaling), delta_mesh (this
    snapshot's A/R^2 - 4 pi), ellipsoid (center, axes, rotation), A_p (per triangle, rule average), A_p_bar,
    u_tilde, Delta_tilde, areas.
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
    both = project(np.stack([(q.radius - q.R) / q.R, A_nodes / q.R]), q.theta, q.phi, q.weights, l_max)
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


# --------------------------------------------------------------------------- mesh bias (issue 7)
#: degrees at which the icosahedral group has invariant harmonics (l <= 30), and the even degrees without any


