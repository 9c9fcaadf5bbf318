"""morphology_metrics: the metrics of one height field in one call, their invariances and their refusals."""

import numpy as np
import pytest

from vesicle_core.analysis import pattern_synth as ps
from vesicle_core.analysis.morphology import (
    characteristic_degree,
    ec_asymmetry,
    low_degree_fraction,
    morphology_metrics,
)
from vesicle_core.errors import ConfigError
from vesicle_core.geometry.mesh import ellipsoid_from_sphere, icosphere
from vesicle_core.geometry.surface import vertex_average


@pytest.fixture(scope="module")
def sphere():
    return icosphere(5)


@pytest.mark.parametrize("l", [4, 10, 16])
def test_characteristic_degree_of_a_single_degree_field(sphere, l):
    v, f = sphere
    h = ps.random_isotropic_field(v, [l], np.random.default_rng(l))
    l_c, lam = characteristic_degree(v, f, h)
    assert l_c == pytest.approx(l, rel=0.02)
    assert lam == pytest.approx(2 * np.pi / np.sqrt(l * (l + 1)), rel=0.03)


def test_low_degree_fraction_separates_lobes_from_wrinkles(sphere):
    v, f = sphere
    rng = np.random.default_rng(0)
    assert low_degree_fraction(v, f, ps.random_isotropic_field(v, [4], rng)) == pytest.approx(1.0, abs=0.01)
    assert low_degree_fraction(v, f, ps.random_isotropic_field(v, [12], rng)) < 0.01
    mix = ps.random_isotropic_field(v, [5], rng) + ps.random_isotropic_field(v, [14], rng)
    expect = 11 / (11 + 29)  # equal coefficients: variance in proportion to 2l + 1
    assert low_degree_fraction(v, f, mix) == pytest.approx(expect, abs=0.15)


def test_ec_asymmetry_changes_sign_exactly_under_h_to_minus_h():
    v, f = icosphere(4)
    rng = np.random.default_rng(1)
    for cls in ps.CLASSES:
        h = ps.sample(cls, v, rng, noise=0.1)
        a, b = morphology_metrics(v, f, h, scales=(0.5,)), morphology_metrics(v, f, -h, scales=(0.5,))
        assert b.ec_asymmetry == -a.ec_asymmetry
        assert b.crest_alignment == pytest.approx(a.crest_alignment, abs=1e-12)
        assert b.low_degree_fraction == pytest.approx(a.low_degree_fraction, abs=1e-12)
        assert b.anisotropy == pytest.approx(a.anisotropy, abs=1e-12)


def test_ec_asymmetry_of_hexagons_and_of_a_curve_without_topology():
    assert ec_asymmetry([-1, 1], [2, 0]) == 0.0
    assert ec_asymmetry([-1, 1], [2, 30]) == 1.0
    assert ec_asymmetry([-1, 1], [-28, 0]) == -1.0
    with pytest.raises(ConfigError, match="pairs"):
        ec_asymmetry([-1, 0.5], [2, 0])


def test_metrics_on_a_wrinkled_ellipsoid_with_triangle_values():
    v0, f = icosphere(4)
    v = ellipsoid_from_sphere(v0, f, axes=(1.3, 0.8, 1.0))
    h = ps.sample("ripples", v0, np.random.default_rng(2), k=10)
    m = morphology_metrics(v, f, h[f].mean(axis=1))
    assert m.l_c == pytest.approx(m.l_c, rel=0)  # finite
    assert 6 < m.l_c < 14
    assert np.all(m.total_charge == 2.0)
    assert m.crest_alignment > 0.8
    s = m.summary()
    assert {"l_c", "ec_asymmetry", "anisotropy_0.5", "defect_density_2", "crest_alignment"} <= set(s)
    assert m.anisotropy[0] >= m.anisotropy[-1]  # coherence can only be lost at larger scales for ripples here
    # triangle values are averaged to the vertices, the same as passing the vertex average
    m2 = morphology_metrics(v, f, vertex_average(v, f, h[f].mean(axis=1)), scales=(0.5,))
    assert m2.crest_alignment == pytest.approx(m.crest_alignment, abs=1e-12)


def test_bad_input_is_refused(sphere):
    v, f = sphere
    with pytest.raises(ConfigError, match="constant"):
        morphology_metrics(v, f, np.ones(len(v)))
    with pytest.raises(ConfigError, match="per vertex"):
        morphology_metrics(v, f, np.ones(5))
    with pytest.raises(ConfigError, match="scales"):
        morphology_metrics(v, f, v[:, 0], scales=(-1.0,))
    with pytest.raises(ConfigError, match="NaN"):
        morphology_metrics(v, f, np.full(len(v), np.nan))


@pytest.mark.parametrize("cls", ["ripples", "hexagons_up", "labyrinth"])
def test_a_wrinkled_ellipsoidal_vesicle_gives_back_its_wrinkles_and_their_class(cls):
    """r = r_ell (1 + eps w): the height about the fitted ellipsoid is eps r_ell w (correlation > 0.99), and the
    classifier names the pattern the wrinkles were drawn from."""
    from vesicle_core.analysis.morphology import height_about_ellipsoid
    from vesicle_core.analysis.pattern_class import classify

    v0, f = icosphere(5)
    w = ps.sample(cls, v0, np.random.default_rng(3), k=13)
    ell = ellipsoid_from_sphere(v0, f, axes=(1.3, 0.8, 0.95))
    v = ell * (1 + 0.01 * w)[:, None]
    h, fit = height_about_ellipsoid(v, f)
    expect = 0.01 * w * np.linalg.norm(ell, axis=1)
    assert np.corrcoef(h, expect)[0, 1] > 0.99
    assert classify(v, f, h) == cls
