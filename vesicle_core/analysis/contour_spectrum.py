"""The spectrum of a membrane's contour in the focal plane: the wavenumber k_* an experimenter measures.

The contour (from :mod:`section` or from an image) is read as its radius r(theta) about a centre, on n_theta rays
at equal angles theta from e1 (the flow's extension axis x in the default plane), and detrended by the section of
the fitted ellipsoid: h(theta) = r(theta) - rho(theta), rho the distance from the same centre to the ellipsoid's
section along the same ray. The centre is the ellipsoid's centre projected on the plane (in a run, the vesicle's
centre X_C of eq. 30): the contour's own centroid would remove its k = 1 content and bias k_rms upwards.

From the Fourier coefficients c_k of h (P_k = |c_k|^2, summed over +-k):

* ``k_star`` -- the 2D analogue of eq. (31): sqrt(sum_{k>=3} k^2 P_k / sum_{k>=3} P_k). Eq. (31) weights
  u_lm^2 by 1/((l - 1)(l + 2)), which undoes eq. (30)'s scaling, so it is the rms degree of the raw shape spectrum
  above the ellipsoid's modes; here likewise of the raw contour spectrum above k = 2. NaN when the wrinkles'
  amplitude (rms of the k >= 3 part) is below ``resolution``.
* ``k_rms`` -- sqrt(sum_k k^2 P_k / sum_k P_k) with k = 0 included: the level of h = 0 is the ellipsoid, not the
  contour's mean, so k_rms^2 = <h'^2> / <h^2> is the ratio in Rice's formula.
  Over an ensemble, average the spectra first (:func:`mean_spectrum_k_rms`): the mean of the per-contour ratios is
  biased low by Jensen's inequality (-4 to -6 % for isotropic degree-l patterns, l = 8-24, 3000 contours each).
* ``up_crossings`` -- upward crossings of the reference level h = 0 (with a hysteresis of +-resolution / 2).
  Rice's formula: their mean number per turn is sqrt(<h'^2> / <h^2>). For an isotropic pattern of degree l,
  <h'^2> / <h^2> on a great circle is l (l + 1) / 2, so both k_rms and the up-crossings are about 0.71 l.
* ``crests`` -- local maxima of h that h falls below by ``resolution`` on either side: the bumps one counts by eye.
  For an isotropic pattern they are about sqrt(<h''^2> / <h'^2>) ~ 0.87 l per turn; a sectoral Y_ll gives l.
* ``variance_by_angle`` -- the mean square of the wrinkles (the k >= 3 part of h) in ``n_bins`` equal sectors of
  theta: where along the contour the wrinkle variance sits.

Crossings and crests are counted on h low-passed to k <= ``k_max`` (what the mesh or the optics resolve).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from .section import Contour, Plane

__all__ = ["ContourSpectrum", "radius_on_rays", "ellipsoid_section_radius", "profile_spectrum",
           "contour_spectrum", "mean_spectrum_k_rms", "K_STAR_MIN"]

K_STAR_MIN = 3  # eq. (31) sums from l = 3: the ellipsoid's modes (0, 1, 2) are not wrinkles


@dataclass(frozen=True)
class ContourSpectrum:
    """The measures of one contour (lengths in the contour's unit). ``power[k]`` is P_k, k = 0..n_theta / 2."""

    theta: np.ndarray
    h: np.ndarray
    power: np.ndarray
    k_star: float
    k_rms: float
    up_crossings: int
    crests: int
    wrinkle_rms: float
    variance_by_angle: np.ndarray
    star_shaped: bool


def _perp_dot(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def radius_on_rays(uv, center, theta) -> tuple[np.ndarray, bool]:
    """Distance from ``center`` (2,) to the closed polygon ``uv`` (n, 2) along rays at angles ``theta``, exactly
    (ray-segment intersections). Where a ray crosses the contour more than once (a fold) the outermost crossing is
    taken, as a radial intensity profile coming from outside would. -> (r (n_theta,), whether every ray crossed once).
    """
    p = np.asarray(uv, float) - np.asarray(center, float)
    q = np.roll(p, -1, axis=0) - p
    d = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    den = _perp_dot(d[:, None, :], q[None, :, :])  # (n_theta, n_seg)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = _perp_dot(p[None, :, :], q[None, :, :]) / den
        t = _perp_dot(p[None, :, :], d[:, None, :]) / den
    # a ray through a polygon vertex meets both its segments at t = 1 and t = 0, each up to round-off: accept a
    # little overlap, and count crossings apart by more than round-off only
    hit = (t >= -1e-9) & (t <= 1.0 + 1e-9) & (s > 0.0) & np.isfinite(s)
    if np.any(~hit.any(axis=1)):
        raise ConfigError("contour spectrum: the centre lies outside the contour (some rays never cross it)")
    r = np.where(hit, s, -np.inf).max(axis=1)
    inner = hit & (s < r[:, None] * (1.0 - 1e-7))
    return r, not bool(inner.any())


def ellipsoid_section_radius(where: Plane, ellipsoid, center_uv, theta) -> np.ndarray:
    """Distance from the in-plane point ``center_uv`` to the ellipsoid (center, axes, rotation) of
    :func:`shape.fit_ellipsoid` along in-plane rays at ``theta``: the section of the fitted ellipsoid."""
    c, axes, rot = (np.asarray(x, float) for x in ellipsoid)
    o = where.to_space(np.asarray(center_uv, float)[None])[0]
    d = np.cos(theta)[:, None] * where.e1 + np.sin(theta)[:, None] * where.e2
    scale = rot / axes[None, :]  # body coordinates over semi-axes: x -> (x - c) @ rot / axes
    a = ((d @ scale) ** 2).sum(axis=1)
    w = (o - c) @ scale
    b = 2.0 * (d @ scale) @ w
    cc = w @ w - 1.0
    if cc >= 0:
        raise ConfigError("contour spectrum: the centre lies outside the fitted ellipsoid's section")
    return (-b + np.sqrt(b * b - 4.0 * a * cc)) / (2.0 * a)


def _up_crossings(h, band):
    """Upward crossings of 0 of a periodic sequence with a Schmitt trigger at +-band / 2."""
    state = np.where(h > band / 2, 1, np.where(h < -band / 2, -1, 0))
    s = state[state != 0]
    if s.size == 0:
        return 0
    return int(np.sum((s == 1) & (np.roll(s, 1) == -1)))


def _crests(h, drop):
    """Maxima of a periodic sequence that the sequence falls below by at least ``drop`` on both sides before it
    rises to a higher one (a zigzag filter: maxima of prominence >= drop)."""
    x = np.roll(h, -int(np.argmin(h)))  # start at the global minimum: no crest at the seam
    drop = max(float(drop), 1e-12 * float(np.ptp(x)), 1e-300)
    count, rising, top, bottom = 0, True, x[0], x[0]
    for value in np.append(x[1:], x[0]).tolist():
        if rising:
            if value > top:
                top = value
            elif top - value >= drop:
                count, rising, bottom = count + 1, False, value
        elif value < bottom:
            bottom = value
        elif value - bottom >= drop:
            rising, top = True, value
    return count


def profile_spectrum(theta, h, *, k_max=None, resolution=0.0, n_bins=16) -> ContourSpectrum:
    """The measures of a detrended profile ``h`` sampled at ``n`` equal angles ``theta`` (see the module)."""
    h = np.asarray(h, float)
    n = h.size
    if n < 16 or n % 2:
        raise ConfigError(f"contour spectrum: n_theta must be even and >= 16, got {n}")
    check_range("resolution", resolution, 0.0, None)
    c = np.fft.rfft(h) / n
    k = np.arange(c.size)
    power = np.abs(c) ** 2
    power[1:(n + 1) // 2] *= 2.0
    k_max = c.size - 1 if k_max is None else int(check_range("k_max", k_max, K_STAR_MIN, None, integer=True))
    power_r = np.where(k <= k_max, power, 0.0)
    total = power_r.sum()
    k_rms = math.sqrt((k**2 * power_r).sum() / total) if total > 0 else float("nan")
    wr = power_r[K_STAR_MIN:]
    wrinkle_rms = math.sqrt(wr.sum())
    k_star = (math.sqrt((k[K_STAR_MIN:] ** 2 * wr).sum() / wr.sum())
              if wrinkle_rms > max(resolution, 0.0) and wr.sum() > 0 else float("nan"))
    smooth = np.fft.irfft(np.where(k <= k_max, c, 0.0) * n, n)
    wrinkles = np.fft.irfft(np.where((k >= K_STAR_MIN) & (k <= k_max), c, 0.0) * n, n)
    check_range("n_bins", n_bins, 1, n, integer=True)
    sector = np.minimum((np.mod(theta, 2 * np.pi) / (2 * np.pi) * n_bins).astype(int), n_bins - 1)
    var = np.bincount(sector, wrinkles**2, n_bins) / np.maximum(np.bincount(sector, None, n_bins), 1)
    return ContourSpectrum(np.asarray(theta, float), h, power, k_star, k_rms, _up_crossings(smooth, resolution),
                           _crests(smooth, resolution), wrinkle_rms, var, True)


def contour_spectrum(contour: Contour, where: Plane, ellipsoid, *, n_theta=512, k_max=None, resolution=None,
                     n_bins=16) -> ContourSpectrum:
    """The spectrum of a section's ``contour`` in plane ``where``, detrended by the section of ``ellipsoid``
    (center, axes, rotation). ``resolution`` defaults to 1e-3 of the ellipsoid's mean semi-axis (0.1 px at
    R = 18 um and 0.16 um pixels: what a microscope can see)."""
    n_theta = int(check_range("n_theta", n_theta, 16, 2**16, integer=True))
    theta = 2.0 * np.pi * np.arange(n_theta) / n_theta
    center = where.to_plane(np.asarray(ellipsoid[0], float)[None])[0]
    if resolution is None:
        resolution = 1e-3 * float(np.mean(ellipsoid[1]))
    r, star = radius_on_rays(contour.uv, center, theta)
    rho = ellipsoid_section_radius(where, ellipsoid, center, theta)
    s = profile_spectrum(theta, r - rho, k_max=k_max, resolution=resolution, n_bins=n_bins)
    return ContourSpectrum(**{**s.__dict__, "star_shaped": star})


def mean_spectrum_k_rms(powers, k_max=None) -> float:
    """k_rms of the ensemble: sqrt(sum_k k^2 <P_k> / sum_k <P_k>) over the rows of ``powers`` (n_contours, n_k), the
    average of which Rice's formula speaks."""
    P = np.asarray(powers, float).mean(axis=0)
    k = np.arange(P.size)
    if k_max is not None:
        P = np.where(k <= k_max, P, 0.0)
    return math.sqrt((k**2 * P).sum() / P.sum())
