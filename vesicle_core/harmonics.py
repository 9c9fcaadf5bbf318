"""Spherical-harmonic analysis of a triangulated vesicle (Sec. III eq. 10, Sec. V eqs. 30-32).

Conventions
-----------
* Lengths in R. Complex, orthonormal spherical harmonics with the Condon-Shortley phase, identical to
  ``scipy.special.sph_harm_y(l, m, theta, phi)`` (theta polar, phi azimuth)::

      Y_lm = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!) P_l^m(cos theta) exp(i m phi),   Y_{l,-m} = (-1)^m conj(Y_lm)

  They are evaluated by the standard stable three-term recurrence of the normalised associated Legendre
  functions (one pass per order m, nothing of size (n_modes x n_points) is ever stored), so l_max = 64 on
  5*10^4 triangles costs a fraction of a second.
* Coefficient arrays have shape (..., l_max + 1, 2 l_max + 1): ``u[..., l, l_max + m]`` is u_lm; entries with
  |m| > l are 0 (datasets.py stores them as NaN). All analysed fields are real, so u_{l,-m} = (-1)^m conj(u_lm);
  only m >= 0 is computed and the rest filled by that symmetry.
* Projection uses conj(Y_lm): c_lm = sum_i f_i conj(Y_lm(theta_i, phi_i)) dOmega_i. Eq. (30) and (32) print Y_lm;
  for a real field that gives conj(c_lm) = (-1)^m c_{l,-m}, which has the same |c_lm| and Delta_l, but only the
  conjugated projection inverts eq. (10) (r = R [1 + sum c_lm Y_lm]).

Scaled amplitudes (eq. 30)
--------------------------
``u_lm = sqrt((l-1)(l+2)/Delta) c_lm`` with ``c_lm = int (r - R)/R conj(Y_lm) dOmega``. For l = 0, 1 the
factor is 0 or undefined, so **u_00 and u_1m hold the unscaled c_lm** (u_00 ~ 0 when R is the equivalent radius,
u_1m ~ 0 when the centre is the volume centroid). With this normalisation a quasi-spherical shape has
sum_{l>=2, m} |u_lm|^2 = 2 (Delta = sum_{l>=2} (l-1)(l+2)/2 sum_m |c_lm|^2 to second order in the shape
perturbation; see :func:`excess_area`).

Quadrature (documented choices, both measured in tests/test_harmonics.py)
--------------------------------------------------------------------------
* Centre X_C: the *volume* centroid of the enclosed solid (divergence theorem). It does not depend on how
  densely the membrane is meshed, and it makes the l = 1 coefficients vanish to first order.
* Sample points: one per triangle, in the direction of the triangle centroid (eq. 30: "geometric centre of the
  i-th triangle").
* Radius sampled per triangle, ``sample=``:
  ``"vertices"`` (default): mean distance of the triangle's three vertices from X_C. The vertices are the
  Lagrangian membrane points; this samples the smooth surface through them.
  ``"centroid"`` (eq. 30 literally): distance of the centroid. A flat facet lies inside the smooth surface by
  ~ (edge)^2 / 8 R, a mesh-scale pattern that leaks into the icosahedral modes l = 6, 10, 12, ... .
* Weights, ``weights=``:
  ``"solid_angle"`` (default): the exact solid angle the triangle subtends at X_C (Van Oosterom & Strackee,
  signed, so the weights sum to exactly 4 pi on any closed surface around X_C).
  ``"paper"``: dOmega_i = A_i / r_i^2 as printed under eq. (30). That is the solid angle only for facets
  perpendicular to the ray; tilted facets (elongated shapes, wrinkles) are over-weighted by 1 / cos(tilt), and the
  weights no longer sum to 4 pi.

Wrinkle amplitude (Sec. V.C)
----------------------------
The surface is fitted by a general (rotated) ellipsoid (:func:`fit_ellipsoid`). A_p is the *radial* deviation of
the membrane from that ellipsoid along the ray from the ellipsoid's centre, positive outside: per vertex
``|X - c| - r_ell(direction)``, and per triangle the mean over its three vertices (``sample="vertices"``) or the
value at its centroid (``sample="centroid"``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .errors import ConfigError, MeshError, check_range

__all__ = [
    "ResolutionWarning",
    "SurfaceSampling",
    "volume_centroid",
    "triangle_areas",
    "solid_angles",
    "resolvable_l_max",
    "sample_surface",
    "project",
    "synthesize",
    "ylm",
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
SAMPLES = ("vertices", "centroid")


class ResolutionWarning(UserWarning):
    """l_max asks for wavelengths the mesh cannot represent (more than about one mode per two edges)."""


# --------------------------------------------------------------------------- geometry
def _as_mesh(vertices, faces):
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must have shape (V, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise MeshError(f"faces must have shape (F, 3), got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        raise MeshError(f"faces must hold integer vertex indices, got dtype {f.dtype}")
    if len(f) == 0 or f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"face indices must lie in [0, {len(v) - 1}]")
    if not np.all(np.isfinite(v)):
        raise MeshError("vertices contain NaN or Inf")
    return v, f.astype(np.int64, copy=False)


def triangle_areas(vertices, faces) -> np.ndarray:
    """Area of every triangle, shape (F,)."""
    v, f = _as_mesh(vertices, faces)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def volume_centroid(vertices, faces) -> np.ndarray:
    """Centroid of the solid enclosed by a closed, outward-oriented surface (sum over tetrahedra to a
    reference point; computed relative to the vertex mean to avoid round-off far from the origin)."""
    v, f = _as_mesh(vertices, faces)
    o = v.mean(axis=0)
    a, b, c = v[f[:, 0]] - o, v[f[:, 1]] - o, v[f[:, 2]] - o
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    V = vol.sum()
    if not V > 0:
        raise MeshError(f"enclosed volume is {V:g}; the surface must be closed with outward normals")
    return o + (vol[:, None] * (a + b + c)).sum(axis=0) / (4.0 * V)


def solid_angles(vertices, faces, center) -> np.ndarray:
    """Signed solid angle each triangle subtends at ``center`` (Van Oosterom & Strackee 1983).

    Positive for triangles seen counter-clockwise from the centre's outside; sums to 4 pi on a closed outward
    surface enclosing ``center``.
    """
    v, f = _as_mesh(vertices, faces)
    c0 = np.asarray(center, dtype=float)
    a, b, c = v[f[:, 0]] - c0, v[f[:, 1]] - c0, v[f[:, 2]] - c0
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    num = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", a, c) * lb
           + np.einsum("ij,ij->i", b, c) * la)
    return 2.0 * np.arctan2(num, den)


def _equivalent_radius(v, f) -> float:
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    vol = float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
    if not vol > 0:
        raise MeshError(f"enclosed volume is {vol:g}; the surface must be closed with outward normals")
    return (3.0 * vol / (4.0 * math.pi)) ** (1.0 / 3.0)


def resolvable_l_max(vertices, faces, R=None) -> int:
    """Largest l the mesh resolves: floor(pi / h), h the mean edge length in radians (h / R).

    A mode l has wavelength 2 pi R / l; representing it needs at least two edges per wavelength.
    Unit icosphere levels 3 / 4 / 5 / 6 give 41 / 83 / 167 / 334 (mean edge 0.075 / 0.038 / 0.019 / 0.0094 R) --
    note that at level 3 this is about 20.
    """
    v, f = _as_mesh(vertices, faces)
    if R is None:
        R = _equivalent_radius(v, f)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    h = np.linalg.norm(v[e[:, 1]] - v[e[:, 0]], axis=1).mean() / R
    return int(math.floor(math.pi / h))


@dataclass
class SurfaceSampling:
    """One quadrature point per triangle: direction (theta, phi) seen from ``center``, sampled radius
    ``radius``, weight ``weights`` (solid angle), triangle ``areas``; ``R`` the reference radius."""

    center: np.ndarray
    R: float
    theta: np.ndarray
    phi: np.ndarray
    radius: np.ndarray
    weights: np.ndarray
    areas: np.ndarray
    weights_kind: str
    sample: str


def _check_choice(name, value, allowed):
    if value not in allowed:
        raise ConfigError(f"{name} must be one of {allowed}, got {value!r}")


def sample_surface(vertices, faces, center=None, R=None, weights="solid_angle", sample="vertices") -> SurfaceSampling:
    """Quadrature points of eq. (30) on a closed triangulated surface (see the module docstring for the choices).

    center: default the volume centroid; R: default the equivalent radius (sphere of equal volume).
    """
    _check_choice("weights", weights, WEIGHTS)
    _check_choice("sample", sample, SAMPLES)
    v, f = _as_mesh(vertices, faces)
    c0 = volume_centroid(v, f) if center is None else np.asarray(center, dtype=float).reshape(3)
    if R is None:
        R = _equivalent_radius(v, f)
    check_range("R", R, 0.0, None, lo_open=True)
    rel = v - c0
    cen = rel[f].mean(axis=1)
    rc = np.linalg.norm(cen, axis=1)
    if np.any(rc == 0):
        raise MeshError("a triangle centroid coincides with the centre; the surface is not star-shaped about it")
    theta = np.arccos(np.clip(cen[:, 2] / rc, -1.0, 1.0))
    phi = np.arctan2(cen[:, 1], cen[:, 0])
    if sample == "vertices":
        radius = np.linalg.norm(rel, axis=1)[f].mean(axis=1)
    else:
        radius = rc
    a, b, c = rel[f[:, 0]], rel[f[:, 1]], rel[f[:, 2]]
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    if weights == "solid_angle":
        w = solid_angles(v, f, c0)
    else:
        w = areas / rc**2
    return SurfaceSampling(c0, float(R), theta, phi, radius, w, areas, weights, sample)


# --------------------------------------------------------------------------- spherical harmonics
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
    for m, P in _legendre_rows(x, s, l_max):
        gr = fw * np.cos(m * phi)  # Re of f w exp(-i m phi)
        gi = -fw * np.sin(m * phi)
        c = (P @ gr.T) + 1j * (P @ gi.T)  # (l_max - m + 1, k)
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
    for m, P in _legendre_rows(np.cos(th), np.sin(th), l_max):
        s = c[m:, l_max + m] @ P  # sum_l c_lm P_lm, complex (N,)
        val = s * np.exp(1j * m * ph)
        out += val.real if m == 0 else 2.0 * val.real
    return out.reshape(shape)


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


def decompose(vertices, faces, l_max, delta=None, R=None, center=None, *, weights="solid_angle",
              sample="vertices") -> np.ndarray:
    """Scaled amplitudes u_lm of eq. (30), complex (l_max+1, 2 l_max+1), index [l, l_max + m].

    delta: the vesicle's excess area Delta used in the scale factor (default: this mesh's own
    A/R^2 - 4 pi). R: reference radius (default: equivalent radius from the enclosed volume). center: default the
    volume centroid. l = 0, 1 entries are the unscaled coefficients. Warns (ResolutionWarning) if l_max exceeds
    :func:`resolvable_l_max`.
    """
    l_max = _check_lmax(l_max)
    v, f = _as_mesh(vertices, faces)
    smp = sample_surface(v, f, center=center, R=R, weights=weights, sample=sample)
    _warn_resolution(v, f, smp.R, l_max)
    if delta is None:
        delta = smp.areas.sum() / smp.R**2 - 4.0 * math.pi
    c = project((smp.radius - smp.R) / smp.R, smp.theta, smp.phi, smp.weights, l_max)
    return c * scale_factors(l_max, delta)[:, None]


def delta_l(u) -> np.ndarray:
    """Delta_l = sum_m |u_lm|^2, shape (..., l_max+1); NaN entries (|m| > l in datasets) are ignored."""
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


def l_max_nontrivial(u, threshold=1e-5):
    """Largest l with some |u_lm| > threshold (Sec. V.A); -1 if none. Works on (..., l, m) arrays."""
    a = np.abs(np.nan_to_num(np.asarray(u), nan=0.0))
    big = (a > threshold).any(axis=-1)  # (..., l)
    L = big.shape[-1]
    last = L - 1 - np.argmax(big[..., ::-1], axis=-1)
    out = np.where(big.any(axis=-1), last, -1)
    return int(out) if np.ndim(out) == 0 else out.astype(int)


def characteristic_l(Delta_l, l_max=None):
    """Characteristic wrinkle mode l_* of eq. (31):

        l_*^2 = sum_{3<=l<=l_max} l^2/(l^2+l-2) Delta_l / sum_{3<=l<=l_max} 1/(l^2+l-2) Delta_l

    Delta_l: (..., L) indexed by l from 0; l_max: int or array broadcastable to the leading shape
    (default: L - 1). NaN where the denominator vanishes (no l >= 3 content). Since Delta_l / (l^2+l-2) is
    |c_lm|^2 summed over m, this is the rms l of the unscaled radial-deviation spectrum.
    """
    D = np.nan_to_num(np.asarray(Delta_l, dtype=float), nan=0.0)
    L = D.shape[-1]
    l = np.arange(L, dtype=float)
    if l_max is None:
        l_max = L - 1
    lm = np.asarray(l_max)
    mask = (l >= 3) & (l <= lm[..., None])
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
        from scipy.spatial.transform import Rotation

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
        del Rotation
    axes, rot = _order_to_lab(a0, R0)
    return np.asarray(c0, float), axes, rot


def wrinkle_amplitude(vertices, faces, ellipsoid, sample="vertices") -> np.ndarray:
    """A_p per triangle: radial deviation of the membrane from the fitted ``ellipsoid`` (center, axes, rotation)
    along the ray from the ellipsoid centre, positive outside, in the units of the vertices.

    sample="vertices": mean of the deviations of the triangle's three vertices (zero to round-off for a mesh whose
    vertices lie on the ellipsoid); "centroid": deviation of the triangle centroid (includes the facet's own
    inward offset ~ edge^2 / 8R).
    """
    _check_choice("sample", sample, SAMPLES)
    v, f = _as_mesh(vertices, faces)
    if sample == "vertices":
        return _radial_deviation(v, ellipsoid)[f].mean(axis=1)
    return _radial_deviation(v[f].mean(axis=1), ellipsoid)


def mean_square_amplitude(A_p, areas) -> float:
    """A_p-bar = (1/A) sum_i A_p,i^2 A_i (Sec. V.C), A = sum_i A_i; units of A_p squared."""
    A_p = np.asarray(A_p, float)
    areas = np.asarray(areas, float)
    if A_p.shape != areas.shape:
        raise ConfigError(f"A_p and areas must have the same shape, got {A_p.shape} and {areas.shape}")
    return float((A_p**2 * areas).sum() / areas.sum())


def amplitude_spectrum(vertices, faces, A_p, l_max, center=None, R=None, *, weights="solid_angle"):
    """u~_lm of eq. (32), u~_lm = sum_i (A_p,i / R) conj(Y_lm(theta_i, phi_i)) dOmega_i (not scaled), and
    Delta~_l = sum_m |u~_lm|^2. Angles and weights as in :func:`decompose` (centre default: volume centroid).

    Returns (u_tilde (l_max+1, 2 l_max+1) complex, Delta_tilde (l_max+1,)).
    """
    l_max = _check_lmax(l_max)
    v, f = _as_mesh(vertices, faces)
    A_p = np.asarray(A_p, float)
    if A_p.shape != (len(f),):
        raise ConfigError(f"A_p must hold one value per triangle ({len(f)}), got shape {A_p.shape}")
    smp = sample_surface(v, f, center=center, R=R, weights=weights)
    _warn_resolution(v, f, smp.R, l_max)
    ut = project(A_p / smp.R, smp.theta, smp.phi, smp.weights, l_max)
    return ut, delta_l(ut)


def analyze_snapshot(vertices, faces, l_max, delta=None, R=None, *, weights="solid_angle", sample="vertices",
                     threshold=1e-5, warn=True) -> dict:
    """Everything Sec. V computes for one snapshot, with a single pass of the harmonic recurrence.

    Returns a dict: u, Delta_l, l_max_nontrivial, l_star (eq. 31 up to l_max_nontrivial), center, R, delta,
    delta_mesh (this snapshot's A/R^2 - 4 pi), ellipsoid (center, axes, rotation), A_p (per triangle),
    A_p_bar, u_tilde, Delta_tilde, areas.
    """
    l_max = _check_lmax(l_max)
    v, f = _as_mesh(vertices, faces)
    smp = sample_surface(v, f, R=R, weights=weights, sample=sample)
    if warn:
        _warn_resolution(v, f, smp.R, l_max)
    delta_mesh = smp.areas.sum() / smp.R**2 - 4.0 * math.pi
    if delta is None:
        delta = delta_mesh
    ell = fit_ellipsoid(v)
    A_p = wrinkle_amplitude(v, f, ell, sample=sample)
    both = project(np.stack([(smp.radius - smp.R) / smp.R, A_p / smp.R]), smp.theta, smp.phi, smp.weights, l_max)
    u = both[0] * scale_factors(l_max, delta)[:, None]
    ut = both[1]
    D = delta_l(u)
    lmn = l_max_nontrivial(u, threshold)
    return {
        "u": u,
        "Delta_l": D,
        "l_max_nontrivial": lmn,
        "l_star": characteristic_l(D, lmn) if lmn >= 3 else float("nan"),
        "center": smp.center,
        "R": smp.R,
        "delta": float(delta),
        "delta_mesh": float(delta_mesh),
        "ellipsoid": ell,
        "A_p": A_p,
        "A_p_bar": mean_square_amplitude(A_p, smp.areas),
        "u_tilde": ut,
        "Delta_tilde": delta_l(ut),
        "areas": smp.areas,
    }
