"""Where on the vesicle the wrinkle energy sits, and whether it sits where the membrane is compressed (the paper's
Fig. 8 and Sec. V.B claim: wrinkles "concentrated around the poles, where the membrane is compressed").

Energy density: e = h^2 per vertex (h the height about the fitted ellipsoid, A_p), smoothed over one wavelength
(:class:`~.surface_calculus.HeatSmoother`, default sigma = the wavelength of :func:`.morphology.characteristic_degree`)
so that it measures the local wrinkle amplitude squared and not the crest/trough oscillation.

Bands: latitude about ``axis`` (the flow's compressional axis: x after the reversal, where the background flow
-gamma_dot (x, -y, 0) of :mod:`vesicle_core.model.flow` compresses the vesicle along its long axis), folded over
the equator, in equal-area bands of |cos theta_a| (area is uniform in cos theta on a sphere): band 0 is the
equatorial belt, band n-1 the two polar caps. Per band: area fraction, energy fraction (share of int e dA),
enrichment = energy fraction / area fraction (1 everywhere for a uniformly wrinkled vesicle; > 1 at the poles for
polar wrinkles), and the area-weighted mean tension when a tension is given.

Against the tension: the area-weighted Pearson correlation between e and the local tension per vertex (tension per
triangle, as the runs store it, is averaged to the vertices first). Wrinkles driven by compression (negative
tension) give a negative correlation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from ..geometry.surface import _as_mesh, vertex_average, volume_centroid
from .morphology import _vertex_field, characteristic_degree
from .surface_calculus import HeatSmoother

__all__ = ["WrinkleLocation", "wrinkle_location", "weighted_correlation"]


@dataclass
class WrinkleLocation:
    """Band statistics (arrays over bands, equator first) and the energy-tension correlation."""

    axis: np.ndarray
    band_edges: np.ndarray
    area_fraction: np.ndarray
    energy_fraction: np.ndarray
    enrichment: np.ndarray
    tension_mean: np.ndarray | None
    correlation: float
    smoothing: float

    @property
    def polar_enrichment(self) -> float:
        """Enrichment of the polar caps (the last band)."""
        return float(self.enrichment[-1])


def weighted_correlation(x, y, w) -> float:
    """Pearson correlation of x and y with weights w (NaN if either is constant)."""
    w = np.asarray(w, float) / np.sum(w)
    xm, ym = x - (w * x).sum(), y - (w * y).sum()
    sx, sy = math.sqrt((w * xm * xm).sum()), math.sqrt((w * ym * ym).sum())
    return float((w * xm * ym).sum() / (sx * sy)) if sx > 0 and sy > 0 else float("nan")


def _tension_at_vertices(v, f, tension):
    t = np.asarray(tension, float)
    if t.shape == (len(f),):
        t = vertex_average(v, f, t)
    if t.shape != (len(v),):
        raise ConfigError(f"tension must hold one value per vertex ({len(v)}) or per triangle ({len(f)}), "
                          f"got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ConfigError("tension contains NaN or Inf")
    return t


def wrinkle_location(vertices, faces, h, axis, tension=None, *, n_bands=6, smoothing=None,
                     smoother=None) -> WrinkleLocation:
    """Wrinkle energy per latitude band about ``axis`` (3-vector) and its correlation with ``tension`` (per vertex
    or per triangle, optional). h: per vertex or per triangle. smoothing: length of the energy smoothing in the
    units of the vertices (default: one wavelength of h; 0: none). smoother: a HeatSmoother of this surface at that
    length, to reuse its factorisation."""
    v, f = _as_mesh(vertices, faces)
    n_bands = check_range("n_bands", n_bands, 1, 1000, integer=True)
    a = np.asarray(axis, float).reshape(-1)
    if a.shape != (3,) or not np.linalg.norm(a) > 0:
        raise ConfigError(f"axis must be a nonzero 3-vector, got {axis!r}")
    a = a / np.linalg.norm(a)
    x, _ = _vertex_field(v, f, h)
    t = None if tension is None else _tension_at_vertices(v, f, tension)
    sigma = characteristic_degree(v, f, x)[1] if smoothing is None else float(smoothing)
    if smoother is not None and abs(smoother.sigma - sigma) > 1e-12 * max(sigma, 1.0):
        raise ConfigError(f"smoother: its length {smoother.sigma} is not the smoothing {sigma}")
    sm = HeatSmoother(v, f, sigma) if smoother is None else smoother
    e = sm(x * x)
    rel = v - volume_centroid(v, f)
    c = np.abs(rel @ a) / np.linalg.norm(rel, axis=1)
    edges = np.linspace(0.0, 1.0, n_bands + 1)
    band = np.clip(np.searchsorted(edges, c, side="right") - 1, 0, n_bands - 1)
    m = sm.mass
    area = np.bincount(band, weights=m, minlength=n_bands) / m.sum()
    energy = np.bincount(band, weights=m * e, minlength=n_bands) / (m * e).sum()
    tmean = None
    corr = float("nan")
    if t is not None:
        tmean = np.bincount(band, weights=m * t, minlength=n_bands) / np.maximum(
            np.bincount(band, weights=m, minlength=n_bands), 1e-300)
        corr = weighted_correlation(e, t, m)
    return WrinkleLocation(axis=a, band_edges=edges, area_fraction=area, energy_fraction=energy,
                           enrichment=energy / np.maximum(area, 1e-300), tension_mean=tmean, correlation=corr,
                           smoothing=sigma)
