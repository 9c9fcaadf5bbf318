"""A phase-contrast-like image of the membrane near the focal plane, and its contour read back as an experimenter
would.

Optics (:class:`Optics`, physical units). The paper's Table III lists the fluid and membrane, not the microscope, so
the defaults are those of a standard phase-contrast vesicle set-up of the kind Kantsler et al. (2007) used: a dry
40x / NA 0.75 Ph2 objective, green light (550 nm) and a 6.45 um camera pixel (a 2/3" CCD), i.e. 0.161 um per pixel
in the sample. From these:

* lateral point-spread function: a Gaussian of sigma = 0.21 lambda / NA (0.154 um, ~1 px), the Gaussian that best
  matches the Airy disc;
* depth of field: d = lambda n / NA^2 + n e / (M NA) (wave-optical plus detector term; n the immersion index, e the
  camera pixel), 1.19 um with the defaults, within the 0.5-1.8 um of 40x-63x objectives; the membrane's weight
  falls off with its distance z from the focal plane as a Gaussian of full width d.

The image (:func:`render`): every patch of membrane dA at height z above the focal plane adds dA exp(-z^2 / 2
sigma_z^2) at its projection on the focal plane, and the sum is blurred by the PSF. Where the membrane crosses the
focal plane steeply (the outline of a vesicle seen in its equatorial plane) its projected area piles up into a thin
line, so the image shows the section of :mod:`section`, dark on a grey background (the phase-contrast halo is not
modelled). Membrane that runs parallel to the focal plane (a crest whose ridge runs around the contour, e.g. Y_l0
at the equator) stays a line at its own radius: it shifts the outline but cannot make it undulate.

Contour detection (two methods, both sub-pixel):

* :func:`radial_contour` -- intensity profiles along rays from the centre (bicubic interpolation, 1/4 px steps),
  the darkest point on each, refined by a parabola through its three samples: r(theta).
* :func:`normal_contour` -- profiles along the normals of the fitted ellipsoid's section, so that each profile
  crosses the outline once even where a ray from the centre crosses it more than once (a peanut's waist): a closed
  polygon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from ..geometry.surface import cross_rows
from .contour_spectrum import ellipsoid_section_radius
from .section import Contour, Plane

__all__ = ["Optics", "Image", "render", "radial_contour", "normal_contour"]


@dataclass(frozen=True)
class Optics:
    """The microscope, in physical units (lengths in micrometres)."""

    numerical_aperture: float = 0.75
    magnification: float = 40.0
    camera_pixel_um: float = 6.45
    wavelength_um: float = 0.55
    immersion_index: float = 1.0

    def __post_init__(self):
        check_range("numerical_aperture", self.numerical_aperture, 0.05, 1.6)
        check_range("magnification", self.magnification, 1.0, 200.0)
        check_range("camera_pixel_um", self.camera_pixel_um, 0.5, 50.0)
        check_range("wavelength_um", self.wavelength_um, 0.2, 2.0)
        check_range("immersion_index", self.immersion_index, 1.0, 1.6)
        if self.numerical_aperture > self.immersion_index:
            raise ConfigError(f"numerical_aperture = {self.numerical_aperture} exceeds immersion_index = "
                              f"{self.immersion_index}: NA <= n")

    @property
    def pixel_um(self) -> float:
        """Pixel size in the sample plane."""
        return self.camera_pixel_um / self.magnification

    @property
    def psf_sigma_um(self) -> float:
        return 0.21 * self.wavelength_um / self.numerical_aperture

    @property
    def depth_of_field_um(self) -> float:
        n, na = self.immersion_index, self.numerical_aperture
        return self.wavelength_um * n / na**2 + n * self.camera_pixel_um / (self.magnification * na)

    def attrs(self) -> dict:
        return {"numerical_aperture": self.numerical_aperture, "magnification": self.magnification,
                "camera_pixel_um": self.camera_pixel_um, "wavelength_um": self.wavelength_um,
                "immersion_index": self.immersion_index, "pixel_um": self.pixel_um,
                "psf_sigma_um": self.psf_sigma_um, "depth_of_field_um": self.depth_of_field_um}


@dataclass(frozen=True)
class Image:
    """Intensity ``pixels[iy, ix]`` (background 1, membrane darker) of the square grid whose pixel (0, 0) is
    centred at ``origin_uv`` in the plane's coordinates (mesh units), spacing ``pixel`` (mesh units)."""

    pixels: np.ndarray
    origin_uv: np.ndarray
    pixel: float

    def to_pixels(self, uv) -> np.ndarray:
        """(x, y) pixel coordinates of in-plane points (N, 2)."""
        return (np.asarray(uv, float) - self.origin_uv) / self.pixel

    def to_plane(self, xy) -> np.ndarray:
        return self.origin_uv + np.asarray(xy, float) * self.pixel


def _subtriangle_centroids(n):
    """Barycentric (b1, b2) of the centroids of the n^2 equal sub-triangles of a triangle."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    up = (i + j) <= n - 1
    down = (i + j) <= n - 2
    b = np.concatenate([np.stack([i[up] + 1 / 3, j[up] + 1 / 3], 1), np.stack([i[down] + 2 / 3, j[down] + 2 / 3], 1)])
    return b / n


def _membrane_samples(v, f, where, sigma_z, spacing):
    """Points (uv, weight) covering the membrane within 3 sigma_z of the focal plane at ``spacing`` or finer."""
    d = (v - where.origin) @ where.normal
    df = d[f]
    near = (df.min(axis=1) < 3 * sigma_z) & (df.max(axis=1) > -3 * sigma_z)  # weight > 1 %
    fn = f[near]
    tri = v[fn]
    if not len(tri):
        return np.zeros((0, 2)), np.zeros(0)
    edge = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max()
    n = int(min(64, max(1, math.ceil(edge / spacing))))
    b = _subtriangle_centroids(n)
    area = 0.5 * np.linalg.norm(cross_rows(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    # the projection on the plane is affine, so the sub-triangles' points are interpolated in (u, v, z) from the
    # three corners' instead of built in 3D and projected: the same points, a third of the arithmetic
    uv = where.to_plane(v)[fn]
    z = d[fn]
    b1, b2 = b[None, :, 0], b[None, :, 1]
    u = uv[:, None, 0, 0] + b1 * (uv[:, None, 1, 0] - uv[:, None, 0, 0]) + b2 * (uv[:, None, 2, 0] - uv[:, None, 0, 0])
    w_ = uv[:, None, 0, 1] + b1 * (uv[:, None, 1, 1] - uv[:, None, 0, 1]) + b2 * (uv[:, None, 2, 1] - uv[:, None, 0, 1])
    zs = z[:, None, 0] + b1 * (z[:, None, 1] - z[:, None, 0]) + b2 * (z[:, None, 2] - z[:, None, 0])
    w = (area / len(b))[:, None] * np.exp(-0.5 * (zs / sigma_z) ** 2)
    return np.stack([u.ravel(), w_.ravel()], axis=1), w.ravel()


def render(vertices, faces, where: Plane, optics: Optics | None = None, *, length_um: float, center_uv=(0.0, 0.0),
           half_width: float, contrast: float = 0.5) -> Image:
    """The image of the membrane (vertices in mesh units, ``length_um`` micrometres per unit) in the focal plane
    ``where``, over the square of ``half_width`` (mesh units) about ``center_uv``."""
    check_range("length_um", length_um, 0.0, None, lo_open=True)
    check_range("half_width", half_width, 0.0, None, lo_open=True)
    check_range("contrast", contrast, 0.0, 1.0, lo_open=True)
    from scipy.ndimage import gaussian_filter

    optics = Optics() if optics is None else optics
    pixel = optics.pixel_um / length_um
    sigma_z = optics.depth_of_field_um / (2.0 * math.sqrt(2.0 * math.log(2.0))) / length_um
    n_px = 2 * int(math.ceil(half_width / pixel)) + 1
    if n_px > 8192:
        raise ConfigError(f"image of {n_px}^2 pixels: half_width = {half_width} is too large for the pixel size")
    origin = np.asarray(center_uv, float) - (n_px // 2) * pixel
    uv, w = _membrane_samples(np.asarray(vertices, float), np.asarray(faces), where, sigma_z, 0.5 * pixel)
    xy = (uv - origin) / pixel
    x0, y0 = np.floor(xy[:, 0]).astype(int), np.floor(xy[:, 1]).astype(int)
    fx, fy = xy[:, 0] - x0, xy[:, 1] - y0
    inside = (x0 >= 0) & (y0 >= 0) & (x0 < n_px) & (y0 < n_px)
    x0, y0, fx, fy, w = x0[inside], y0[inside], fx[inside], fy[inside], w[inside]
    # bilinear splat onto the four surrounding pixels, as one histogram
    i0 = y0 * (n_px + 1) + x0
    gx, gy = 1 - fx, 1 - fy
    density = np.bincount(np.concatenate([i0, i0 + 1, i0 + n_px + 1, i0 + n_px + 2]),
                          np.concatenate([w * gx * gy, w * fx * gy, w * gx * fy, w * fx * fy]), (n_px + 1) ** 2)
    density = density.reshape(n_px + 1, n_px + 1)[:n_px, :n_px] / pixel**2
    density = gaussian_filter(density, optics.psf_sigma_um / optics.pixel_um, mode="constant")
    peak = density.max()
    return Image(1.0 - contrast * density / peak if peak > 0 else np.ones_like(density), origin, pixel)


def _darkest(image, start_xy, direction_xy, s):
    """Sub-pixel position (in the units of ``s``) of the darkest point of each profile start + s direction."""
    from scipy.ndimage import map_coordinates

    pts = start_xy[:, None, :] + s[None, :, None] * direction_xy[:, None, :]
    prof = map_coordinates(image.pixels, [pts[..., 1], pts[..., 0]], order=3, mode="nearest")
    j = np.clip(np.argmin(prof, axis=1), 1, len(s) - 2)
    rows = np.arange(len(j))
    a, b, c = prof[rows, j - 1], prof[rows, j], prof[rows, j + 1]
    den = a - 2 * b + c
    shift = np.where(den > 0, 0.5 * (a - c) / np.where(den > 0, den, 1.0), 0.0)
    return s[j] + np.clip(shift, -1.0, 1.0) * (s[1] - s[0])


def radial_contour(image: Image, center_uv, theta, r_min, r_max) -> np.ndarray:
    """r(theta) (mesh units) of the darkest line along rays from ``center_uv`` at ``theta``, searched between
    ``r_min`` and ``r_max`` (numbers, or arrays of one per ray, e.g. a band about the fitted ellipse)."""
    r_min = np.broadcast_to(np.asarray(r_min, float), np.shape(theta)) / image.pixel
    r_max = np.broadcast_to(np.asarray(r_max, float), np.shape(theta)) / image.pixel
    if not (np.all(r_min >= 0) and np.all(r_max > r_min)):
        raise ConfigError("radial_contour: the search needs 0 <= r_min < r_max on every ray")
    s = np.arange(0.0, float((r_max - r_min).max()), 0.25)
    d = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    start = image.to_pixels(np.asarray(center_uv, float)[None]) + r_min[:, None] * d
    return (r_min + _darkest(image, start, d, s)) * image.pixel


def normal_contour(image: Image, where: Plane, ellipsoid, n_points=512, search=0.2) -> Contour:
    """The outline along the normals of the fitted ellipsoid's section: ``n_points`` profiles at equal angles
    about its centre, each searched ``search`` (mesh units) either side of the ellipse. -> a Contour."""
    n_points = int(check_range("n_points", n_points, 16, 2**16, integer=True))
    check_range("search", search, 0.0, None, lo_open=True)
    theta = 2 * np.pi * np.arange(n_points) / n_points
    center = where.to_plane(np.asarray(ellipsoid[0], float)[None])[0]
    rho = ellipsoid_section_radius(where, ellipsoid, center, theta)
    base = center + rho[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    tangent = np.roll(base, -1, axis=0) - np.roll(base, 1, axis=0)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)  # outward for a counter-clockwise ellipse
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    s = np.arange(-search / image.pixel, search / image.pixel, 0.25)
    offset = _darkest(image, image.to_pixels(base), normal, s) * image.pixel
    uv = base + offset[:, None] * normal
    return Contour(where.to_space(uv), uv, np.full(n_points, -1))
