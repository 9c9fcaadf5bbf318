"""Synthetic wrinkle patterns on a closed surface, one generator per class of :mod:`.pattern_class`.

Every generator takes unit directions x (N, 3) from the surface's centre (on a unit sphere mesh: the vertices),
a wavenumber k (crests per radian, the pattern's degree l ~ k) and a NumPy Generator for the random choices
(orientation, phases, disorder). Fields are returned with zero mean and unit rms over the points.

* **ripples**: h = cos(k theta_a + phase), crests on the latitudes about a random axis a (the paper's wrinkles
  in a shear-free compression along a: parallel crests, a bull's eye at each pole).
* **herringbone**: the ripples' crests zigzag: theta_a is shifted by tan(alpha) sin(theta_a) zig(n psi) / n, zig a
  unit-slope triangle wave of period 2 pi in the azimuth psi about a, so the crests run at +-alpha to the
  latitudes in n zigs per turn (a zig length of ~3-5 wavelengths on the equator), alpha in [20, 32] degrees,
  the zig positions jittered per band of latitude for the paper's "disordered" herringbone.
* **labyrinth** (wormlike): tanh(2 f / sd(f)) of a random isotropic field f of degrees k-1..k+1: meandering
  crests of all orientations, up-down symmetric in law.
* **hexagons_up / hexagons_down**: Gaussian bumps (width 0.22 d) on the points of a Fibonacci lattice of spacing
  d = 4 pi / (sqrt(3) k) (the spacing of three crossed waves of wavenumber k), randomly rotated, jittered by
  0.05 d: isolated spots up on a connected background; "down" is the negative (holes in a connected network).
* **peanut**: a zonal P_4(cos theta_a) + b P_6(cos theta_a) about a random axis, b in [-0.4, 0.4]: the two lobes
  and the waist of a dumbbell that the fitted ellipsoid cannot follow, no short-wavelength crests.

:func:`add_noise` adds a random isotropic field of degrees 2..2k with a given rms relative to the pattern.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ..errors import ConfigError, check_choice, check_range
from ..geometry.ylm import _angles, synthesize

CLASSES = ("ripples", "herringbone", "labyrinth", "hexagons_up", "hexagons_down", "peanut")

__all__ = ["CLASSES", "random_isotropic_field", "ripples", "herringbone", "labyrinth", "hexagons", "peanut",
           "add_noise", "sample"]


def _unit(x):
    x = np.asarray(x, float)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ConfigError(f"points must have shape (N, 3), got {x.shape}")
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _standard(h):
    h = h - h.mean()
    return h / h.std()


def _axis_angles(x, rng):
    """Polar angle theta_a and azimuth psi about a random axis (a random rotation of the frame)."""
    y = _unit(x) @ Rotation.random(random_state=rng).as_matrix()
    return np.arccos(np.clip(y[:, 2], -1, 1)), np.arctan2(y[:, 1], y[:, 0])


def random_isotropic_field(x, degrees, rng) -> np.ndarray:
    """sum over l in ``degrees`` and m of a_lm Y_lm(x) with independent standard normal coefficients of the real
    orthonormal basis: an isotropic Gaussian field of variance sum_l (2l+1) / (4 pi) (not normalised)."""
    _, theta, phi = _angles(_unit(x))
    degrees = np.atleast_1d(np.asarray(degrees, int))
    if degrees.min() < 0:
        raise ConfigError(f"degrees must be >= 0, got {degrees}")
    l_max = int(degrees.max())
    c = np.zeros((l_max + 1, 2 * l_max + 1), complex)
    for l in degrees:
        c[l, l_max] = rng.standard_normal()
        re, im = rng.standard_normal((2, l))
        c[l, l_max + 1:l_max + l + 1] = (re + 1j * im) / math.sqrt(2.0)
    return synthesize(c, theta, phi)


def ripples(x, k, rng) -> np.ndarray:
    theta, _ = _axis_angles(x, rng)
    return _standard(np.cos(k * theta + rng.uniform(0, 2 * math.pi)))


def _zig(s):
    """Triangle wave of unit slope and period 2 pi, zero mean."""
    return np.abs(np.mod(s, 2 * math.pi) - math.pi) - 0.5 * math.pi


def herringbone(x, k, rng, alpha_deg=None) -> np.ndarray:
    theta, psi = _axis_angles(x, rng)
    alpha = math.radians(rng.uniform(20.0, 32.0) if alpha_deg is None else alpha_deg)
    n = max(2, int(round(k / rng.uniform(3.0, 5.0))))
    bands = np.floor(theta * k / (2 * math.pi) * 0.5)  # jitter the zigs every two wavelengths of latitude
    jitter = rng.uniform(0, 2 * math.pi, size=int(bands.max()) + 1)[bands.astype(int)] * 0.3
    shift = math.tan(alpha) * np.sin(theta) * _zig(n * psi + jitter) / n
    return _standard(np.cos(k * (theta + shift) + rng.uniform(0, 2 * math.pi)))


def labyrinth(x, k, rng) -> np.ndarray:
    kk = int(round(k))
    f = random_isotropic_field(x, [kk - 1, kk, kk + 1], rng)
    return _standard(np.tanh(2.0 * f / f.std()))


def hexagons(x, k, rng, up=True) -> np.ndarray:
    u = _unit(x)
    d = 4 * math.pi / (math.sqrt(3.0) * k)
    n = max(12, int(round(4 * math.pi / (0.5 * math.sqrt(3.0) * d * d))))
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    ang = math.pi * (1 + math.sqrt(5.0)) * i
    s = np.sqrt(1 - z * z)
    p = np.stack([s * np.cos(ang), s * np.sin(ang), z], axis=1) @ Rotation.random(random_state=rng).as_matrix()
    p = p + 0.05 * d * rng.standard_normal(p.shape)
    w = 0.22 * d
    dist, _ = cKDTree(p).query(u, k=min(7, n))
    h = np.exp(-0.5 * (dist / w) ** 2).sum(axis=1)
    return _standard(h if up else -h)


def peanut(x, k, rng) -> np.ndarray:
    theta, _ = _axis_angles(x, rng)
    c = np.cos(theta)
    p4 = (35 * c**4 - 30 * c**2 + 3) / 8
    p6 = (231 * c**6 - 315 * c**4 + 105 * c**2 - 5) / 16
    return _standard(p4 + rng.uniform(-0.4, 0.4) * p6)


def add_noise(x, h, level, k, rng) -> np.ndarray:
    """h + noise with rms ``level`` times rms(h): an isotropic field of degrees 2..2k (flat per coefficient)."""
    check_range("noise level", level, 0.0, 1.0)
    if level == 0:
        return h
    n = random_isotropic_field(x, np.arange(2, int(2 * k) + 1), rng)
    return h + level * h.std() * n / n.std()


_GENERATORS = {
    "ripples": ripples, "herringbone": herringbone, "labyrinth": labyrinth,
    "hexagons_up": lambda x, k, rng: hexagons(x, k, rng, up=True),
    "hexagons_down": lambda x, k, rng: hexagons(x, k, rng, up=False),
    "peanut": peanut,
}


def sample(name, x, rng, *, k=None, noise=0.0) -> np.ndarray:
    """One random field of class ``name`` at points x: k (default uniform in [10, 16]) and noise rms relative."""
    check_choice("pattern class", name, CLASSES)
    k = rng.uniform(10.0, 16.0) if k is None else float(k)
    h = _GENERATORS[name](x, k, rng)
    return add_noise(x, h, noise, k, rng)
