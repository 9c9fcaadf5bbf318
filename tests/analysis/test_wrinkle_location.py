"""Where the wrinkle energy sits: per-band energy against the analytic integral, and its correlation with tension."""

import math

import numpy as np
import pytest

from vesicle_core.analysis import pattern_synth as ps
from vesicle_core.analysis.wrinkle_location import weighted_correlation, wrinkle_location
from vesicle_core.errors import ConfigError
from vesicle_core.geometry.mesh import ellipsoid_from_sphere, icosphere


@pytest.fixture(scope="module")
def sphere():
    return icosphere(5)


def _axis():
    a = np.array([0.3, -0.4, 0.87])
    return a / np.linalg.norm(a)


def _meridional_wrinkles(v, a, p, k=14):
    """h = |z|^p cos(k psi): crests along meridians about a, amplitude growing towards the poles."""
    b = np.cross(a, [0.6, 0.0, 0.8])
    b /= np.linalg.norm(b)
    c = np.cross(a, b)
    z = v @ a
    return np.abs(z) ** p * np.cos(k * np.arctan2(v @ c, v @ b)), z


@pytest.mark.parametrize("p", [0, 1, 2])
def test_band_energy_matches_the_integral_of_the_envelope(sphere, p):
    """Energy fraction in the band c0 <= |cos| < c1 of h = |z|^p cos(k psi): c1^(2p+1) - c0^(2p+1) (the azimuthal
    mean of cos^2 is 1/2 in every band, and dA = dz dpsi on the unit sphere)."""
    v, f = sphere
    a = _axis()
    h, _ = _meridional_wrinkles(v, a, p)
    loc = wrinkle_location(v, f, h, a, smoothing=0.0, n_bands=5)
    e = loc.band_edges
    expect = e[1:] ** (2 * p + 1) - e[:-1] ** (2 * p + 1)
    assert np.allclose(loc.area_fraction, 0.2, atol=0.005)
    assert np.allclose(loc.energy_fraction, expect, atol=0.01), (loc.energy_fraction, expect)
    assert loc.polar_enrichment == pytest.approx(expect[-1] / 0.2, rel=0.05)


def test_polar_wrinkles_anticorrelate_with_a_compressive_polar_tension(sphere):
    v, f = sphere
    a = _axis()
    h, z = _meridional_wrinkles(v, a, 1)
    tension = 1.0 - 3.0 * z**2  # compressive (negative) near the poles
    loc = wrinkle_location(v, f, h, a, tension=tension)
    assert loc.correlation < -0.9
    assert loc.tension_mean[-1] < 0 < loc.tension_mean[0]
    assert loc.polar_enrichment > 2.0
    # the same tension per triangle gives the same answer
    tri = tension[f].mean(axis=1)
    assert wrinkle_location(v, f, h, a, tension=tri).correlation == pytest.approx(loc.correlation, abs=0.01)


def test_uniform_wrinkles_are_not_enriched_anywhere(sphere):
    v, f = sphere
    rng = np.random.default_rng(0)
    h = ps.sample("labyrinth", v, rng, k=14)
    loc = wrinkle_location(v, f, h, _axis(), n_bands=3)
    assert np.allclose(loc.enrichment, 1.0, atol=0.2)


def test_on_an_ellipsoid_the_bands_are_taken_about_the_centroid():
    v0, f = icosphere(4)
    v = ellipsoid_from_sphere(v0, f, axes=(1.5, 0.8, 0.8)) + np.array([3.0, -1.0, 2.0])
    h, _ = _meridional_wrinkles(v0, np.array([1.0, 0, 0]), 2, k=10)
    loc = wrinkle_location(v, f, h, [1, 0, 0], smoothing=0.0, n_bands=4)
    assert loc.energy_fraction[-1] > 0.5 and loc.energy_fraction[0] < 0.05


def test_bad_input_is_refused(sphere):
    v, f = sphere
    h = v[:, 0]
    with pytest.raises(ConfigError, match="axis"):
        wrinkle_location(v, f, h, [0, 0, 0])
    with pytest.raises(ConfigError, match="tension"):
        wrinkle_location(v, f, h, [0, 0, 1], tension=np.ones(7))
    with pytest.raises(ConfigError, match="n_bands"):
        wrinkle_location(v, f, h, [0, 0, 1], n_bands=0)
    assert math.isnan(weighted_correlation(np.ones(4), np.arange(4.0), np.ones(4)))
