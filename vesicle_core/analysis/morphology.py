"""Morphology of the wrinkles: the metrics of one height field h about the fitted ellipsoid, in one call.

h is the radial deviation A_p from the fitted ellipsoid (Sec. V.C; :func:`height_about_ellipsoid` fits the
ellipsoid as :func:`.shape.analyze_snapshot` does and returns A_p at the vertices), or any vertex (or triangle)
field on a closed triangulated surface. The metrics, each defined in its own module:

* characteristic degree l_c and wavelength: l_c (l_c + 1) / R^2 = int |grad h|^2 dA / int h^2 dA (the spectrum's
  mean of l(l+1), exact for a field of one degree on a sphere of radius R = sqrt(A / 4 pi)); wavelength
  2 pi R / sqrt(l_c (l_c + 1)). The scales of the crest metrics are given in these wavelengths.
* Euler curve chi({h >= u sd}) at ``levels`` (:mod:`.excursion`) and its **up-down asymmetry**
  ``A = sum_{u > 0} [chi(u) + chi(-u) - 2] / sum_{u > 0} [|chi(u)| + |chi(-u) - 2|]``, in [-1, 1]: 0 in the mean for
  any field whose law is symmetric under h -> -h (chi(u) + chi(-u) = 2 for a Gaussian field, by the GKF), > 0 for
  isolated bumps on a connected background (hexagons up), and exactly -A for -h (chi_{-h}(u) = 2 - chi_h(-u)).
* **low-degree fraction**: the share of int h^2 dOmega in degrees l <= ``low_l`` (solid-angle quadrature about
  the volume centroid, :mod:`.harmonics`): the large-scale lobes of a peanut, not wrinkles.
* crest alignment P and its axis, and per scale the coherence / anisotropy a_2 and the crest defects
  (:mod:`.crest_order`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from ..geometry.surface import _as_mesh, face_area_vectors, vertex_average
from ..geometry.ylm import project
from .crest_order import CrestOrder, crest_alignment, crest_order
from .excursion import euler_curve
from .harmonics import quadrature
from .shape import fit_ellipsoid, wrinkle_amplitude
from .surface_calculus import HeatSmoother, edge_angles, face_gradients, tangent_frames, vertex_areas

DEFAULT_LEVELS = (-2.0, -1.5, -1.0, -0.5, 0.5, 1.0, 1.5, 2.0)
DEFAULT_SCALES = (0.5, 1.0, 2.0)

__all__ = ["Morphology", "morphology_metrics", "height_about_ellipsoid", "ec_asymmetry", "characteristic_degree",
           "low_degree_fraction", "DEFAULT_LEVELS", "DEFAULT_SCALES"]


@dataclass
class Morphology:
    """Metrics of one height field; lengths in the units of the vertices, ``scales`` in wavelengths."""

    l_c: float
    wavelength: float
    rms: float
    levels: np.ndarray
    euler: np.ndarray
    ec_asymmetry: float
    low_degree_fraction: float
    crest_alignment: float
    crest_axis: np.ndarray
    scales: tuple
    orders: list = field(default_factory=list)

    @property
    def anisotropy(self) -> np.ndarray:
        return np.array([o.anisotropy for o in self.orders])

    @property
    def defect_density(self) -> np.ndarray:
        return np.array([o.defect_density for o in self.orders])

    @property
    def total_charge(self) -> np.ndarray:
        return np.array([o.total_charge for o in self.orders])

    def summary(self) -> dict:
        """Scalars only (for tables and datasets): per-scale values as anisotropy_<s>, defect_density_<s>."""
        out = {"l_c": self.l_c, "wavelength": self.wavelength, "rms": self.rms, "ec_asymmetry": self.ec_asymmetry,
               "low_degree_fraction": self.low_degree_fraction, "crest_alignment": self.crest_alignment}
        for s, o in zip(self.scales, self.orders, strict=True):
            out[f"anisotropy_{s:g}"] = o.anisotropy
            out[f"defect_density_{s:g}"] = o.defect_density
            out[f"total_charge_{s:g}"] = o.total_charge
        return out


def ec_asymmetry(levels, euler) -> float:
    """Up-down asymmetry A of an Euler curve at levels symmetric about 0 (module docstring); 0 when the curve
    carries no topology at all (every chi(u) = 0 and chi(-u) = 2)."""
    u = np.asarray(levels, float)
    chi = np.asarray(euler, float)
    pos = np.sort(u[u > 0])
    lookup = dict(zip(u.tolist(), chi.tolist(), strict=True))
    if not pos.size or any(-p not in lookup for p in pos):
        raise ConfigError(f"levels must come in pairs +-u, got {u.tolist()}")
    num = sum(lookup[p] + lookup[-p] - 2.0 for p in pos)
    den = sum(abs(lookup[p]) + abs(lookup[-p] - 2.0) for p in pos)
    return float(num / den) if den > 0 else 0.0


def characteristic_degree(vertices, faces, values) -> tuple[float, float]:
    """(l_c, wavelength) of the vertex field from its Rayleigh quotient (module docstring)."""
    v, f = _as_mesh(vertices, faces)
    h = np.asarray(values, float)
    g = face_gradients(v, f, h)
    af = np.linalg.norm(face_area_vectors(v, f), axis=1)
    R = math.sqrt(af.sum() / (4.0 * math.pi))
    q = float((af * (g * g).sum(axis=1)).sum() / max((vertex_areas(v, f) * h * h).sum(), 1e-300))
    l_c = -0.5 + math.sqrt(0.25 + R * R * q)
    return l_c, 2.0 * math.pi * R / math.sqrt(max(l_c * (l_c + 1.0), 1e-300))


def low_degree_fraction(vertices, faces, values, low_l=6) -> float:
    """Share of int h^2 dOmega in degrees <= low_l (solid-angle vertex quadrature about the volume centroid)."""
    q = quadrature(vertices, faces, rule="vertex")
    h = np.asarray(values, float)
    c = project(h, q.theta, q.phi, q.weights, int(low_l))
    low = float(np.sum(np.abs(c) ** 2))
    return low / max(float(np.sum(q.weights * h * h)), 1e-300)


def _vertex_field(v, f, values):
    x = np.asarray(values, float)
    if x.shape == (len(f),):
        x = vertex_average(v, f, x)
    if x.shape != (len(v),):
        raise ConfigError(f"h must hold one value per vertex ({len(v)}) or per triangle ({len(f)}), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ConfigError("h contains NaN or Inf")
    m = vertex_areas(v, f)
    x = x - (m * x).sum() / m.sum()
    if not np.any(x):
        raise ConfigError("h is constant: the morphology needs a field that varies")
    return x, float(np.sqrt((m * x * x).sum() / m.sum()))


def morphology_metrics(vertices, faces, h, *, scales=DEFAULT_SCALES, levels=DEFAULT_LEVELS,
                       low_l=6, smoothers=None) -> Morphology:
    """All metrics of the height field ``h`` (per vertex, or per triangle: then averaged to the vertices) on the
    closed surface (vertices, faces). ``scales``: smoothing lengths of the crest metrics in wavelengths;
    ``levels``: Euler-curve levels in units of h's rms, in pairs +-u. ``smoothers``: {scale: HeatSmoother} already
    factorised on this surface at scale x the wavelength (a caller that smooths at the same length reuses them)."""
    v, f = _as_mesh(vertices, faces)
    if not all(s >= 0 for s in scales):
        raise ConfigError(f"scales must be >= 0 (in wavelengths), got {scales}")
    x, rms = _vertex_field(v, f, h)
    l_c, lam = characteristic_degree(v, f, x)
    chi = euler_curve(f, x, levels)
    P, axis = crest_alignment(v, f, x)
    frames = tangent_frames(v, f)
    geometry = edge_angles(v, f, frames)
    orders: list[CrestOrder] = [
        crest_order(v, f, x, s * lam, wavelength=lam, frames=frames, geometry=geometry,
                    smoother=(smoothers or {}).get(s) or HeatSmoother(v, f, s * lam)) for s in scales]
    return Morphology(l_c=l_c, wavelength=lam, rms=rms, levels=np.asarray(levels, float), euler=chi,
                      ec_asymmetry=ec_asymmetry(levels, chi), low_degree_fraction=low_degree_fraction(v, f, x, low_l),
                      crest_alignment=P, crest_axis=axis, scales=tuple(scales), orders=orders)


def height_about_ellipsoid(vertices, faces) -> tuple[np.ndarray, tuple]:
    """(h, ellipsoid): A_p per vertex, the radial deviation from the ellipsoid fitted with vertex-area weights, as
    :func:`.shape.analyze_snapshot` fits it (Sec. V.C). The input of :func:`morphology_metrics` for a snapshot."""
    v, f = _as_mesh(vertices, faces)
    ell = fit_ellipsoid(v, weights=vertex_areas(v, f))
    return wrinkle_amplitude(v, f, ell, at="vertices"), ell
