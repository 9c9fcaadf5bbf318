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
* Fit, ``fit=``: ``"quadrature"`` (default) is the sum above, eq. (30) as printed. Its weights integrate products
  of Y_lm exactly only on regular nodes: on the quasi-uniform meshes (irregular by design) the smooth 1:0.8:1
  ellipsoid shows Delta_l = 2e-4 at l = 40 and 1.5e-3 at l = 48 (5351 vertices; 1.3e-5 and 1.3e-4 at 9512),
  against 9e-7 and 2e-6 on the level-5 icosphere. That floor is there before any dynamics and sits above a
  thermal seed's Delta_l (~1e-6) in the wrinkle band. ``"least_squares"`` fits the coefficients up to l_max in
  the weighted least-squares sense (:func:`~vesicle_core.geometry.ylm.fit_least_squares`, quadrature-
  preconditioned sweeps, 3-4 of them): the same ellipsoid's floor falls to 2e-8 and 6e-8, and its own l = 6-10
  content matches a 40962-vertex icosphere where the quadrature misses l = 8 by 18% (tests). It costs ~4x the
  quadrature. At t_* the wrinkles dwarf the floor: l_* of the S = 2224 run at 256^3 (10242 vertices) is
  26.17 by quadrature and 26.18 by least squares (docs/history/solver.md, "Wrinkling ladders with the sharp coupling").

The fitted ellipsoid, the wrinkle amplitude A_p and one snapshot's whole analysis: :mod:`vesicle_core.analysis.shape`.
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
    dot_rows,
    face_area_vectors,
    pn_centers,
    resolvable_l_max,
    solid_angles,
    volume_centroid,
)
from ..geometry.ylm import _angles, _check_lmax, fit_least_squares, project, synthesize

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
    "t_star_between_frames",
    "l_max_nontrivial",
    "characteristic_l",
]

WEIGHTS = ("solid_angle", "paper")
RULES = ("pn", "vertex", "centroid")
#: how coefficients are read off the nodes: the quadrature sum of eq. (30), or the weighted least-squares fit
#: (:func:`~vesicle_core.geometry.ylm.fit_least_squares`) that removes the quadrature's aliasing floor on
#: irregular meshes (module docstring, "Fit")
FITS = ("quadrature", "least_squares")
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
        w_tri = areas / dot_rows(cen, cen)

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
              weights="solid_angle", fit="quadrature") -> np.ndarray:
    """Scaled amplitudes u_lm of eq. (30), complex (l_max+1, 2 l_max+1), index [l, l_max + m].

    delta: the vesicle's excess area Delta of the scale factor sqrt((l-1)(l+2)/Delta) (default: this mesh's own
    A/R^2 - 4 pi). R: reference radius (default: equivalent radius from the enclosed volume). center: default the
    volume centroid. rule / weights: see the module docstring. fit: ``quadrature`` (eq. 30 as printed) or
    ``least_squares`` (:func:`fit_coefficients`). l = 0, 1 entries are the unscaled coefficients.
    Warns (ResolutionWarning) if l_max exceeds :func:`resolvable_l_max`.
    """
    l_max = _check_lmax(l_max)
    v, f = _as_mesh(vertices, faces)
    q = quadrature(v, f, center=center, R=R, rule=rule, weights=weights)
    _warn_resolution(v, f, q.R, l_max)
    if delta is None:
        delta = q.areas.sum() / q.R**2 - 4.0 * math.pi
    c = fit_coefficients((q.radius - q.R) / q.R, q, l_max, fit)
    return c * scale_factors(l_max, delta)[:, None]


def fit_coefficients(values, q: Quadrature, l_max, fit="quadrature"):
    """Coefficients up to l_max of real node values (N,) or (k, N) on the quadrature q: the quadrature sum
    (``fit="quadrature"``, eq. 30) or its weighted least-squares refinement (``"least_squares"``)."""
    check_choice("fit", fit, FITS)
    if fit == "quadrature":
        return project(values, q.theta, q.phi, q.weights, l_max)
    return fit_least_squares(values, q.theta, q.phi, q.weights, l_max)[0]


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


def t_star_between_frames(time, Delta_2):
    """t_* between the frames: the vertex of the parabola through the sampled minimum of Delta_2 (over time >= 0)
    and its two neighbours -> (t_*, frame indices, weights), where ``weights @ y[indices]`` is any series y(t) at t_*
    by the same parabola's interpolation (quadratic Lagrange weights). NaN, (), () without a finite Delta_2 at
    time >= 0.

    The frame value (:func:`t_star_index`) jumps by a whole frame spacing h when the frames move against a shallow
    minimum; the vertex moves with the minimum. Frames may be unequally spaced (divided differences). With the
    sampled minimum in the middle the parabola's curvature is >= 0 and its vertex lies between the midpoints of that
    frame's two intervals, so the stencil's weights stay bounded (|w| <= 1.125 on equal spacing). Its error: for
    Delta_2 = c2 (t - t0)^2 + c3 (t - t0)^3 on frames h apart, with the middle frame at t0 + s, the vertex is off by
    exactly c3 (3 s^2 - h^2) / (2 c2 + 6 c3 s), at most ~ |c3| h^2 / (2 c2) (zero for a symmetric minimum), where
    the frame value is off by up to h / 2.
    At the ends of the record (the minimum at the first frame at or after the reversal, or at the last frame) there
    is no bracket, so nothing to fit: the frame value, with indices (i,) and weights (1.0,).
    """
    i = t_star_index(time, Delta_2)
    if i < 0:
        return math.nan, (), ()
    t = np.asarray(time, float)
    d = np.asarray(Delta_2, float)
    ok = np.flatnonzero((t >= 0) & np.isfinite(d))
    p = int(np.searchsorted(ok, i))
    if p == 0 or p == ok.size - 1:
        return float(t[i]), (i,), (1.0,)
    idx = (int(ok[p - 1]), i, int(ok[p + 1]))
    (t0, t1, t2), (f0, f1, f2) = t[list(idx)], d[list(idx)]
    d01, d12 = (f1 - f0) / (t1 - t0), (f2 - f1) / (t2 - t1)
    curv = (d12 - d01) / (t2 - t0)  # >= 0: f1 is the smallest of the three
    ts = t1 if curv <= 0 else 0.5 * (t0 + t1) - d01 / (2.0 * curv)
    w = ((ts - t1) * (ts - t2) / ((t0 - t1) * (t0 - t2)), (ts - t0) * (ts - t2) / ((t1 - t0) * (t1 - t2)),
         (ts - t0) * (ts - t1) / ((t2 - t0) * (t2 - t1)))
    return float(ts), idx, tuple(float(x) for x in w)


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
    (docs/history/solver.md, "Tension noise"); the vertex average keeps part of them. The surface must be star-shaped
    about the centre (default: the volume centroid).
    """
    v, f = _as_mesh(vertices, faces)
    if l_max is None:
        l_max = max(1, resolvable_l_max(v, f, R) // 2)
    c0 = volume_centroid(v, f) if center is None else np.asarray(center, dtype=float).reshape(3)
    c = field_spectrum(v, f, values, l_max, center=c0, R=R)
    _, theta, phi = _angles(v - c0)
    return synthesize(c, theta, phi)
