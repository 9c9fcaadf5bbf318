"""Crest orientation order: structure-tensor coherence, crest defects with half-integer charges that add up to the
surface's Euler characteristic (Poincare-Hopf for line fields), and the global crest alignment."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from vesicle_core.analysis import pattern_synth as ps
from vesicle_core.analysis.crest_order import crest_alignment, crest_order
from vesicle_core.analysis.surface_calculus import (
    HeatSmoother,
    face_gradients,
    line_field_index,
    tangent_frames,
)
from vesicle_core.geometry.mesh import ellipsoid_from_sphere, icosphere, quasiuniform_sphere
from vesicle_core.geometry.surface import dot_rows


def _torus(n_u=60, n_v=24, R=1.0, r=0.35):
    u, w = np.meshgrid(np.arange(n_u) * 2 * math.pi / n_u, np.arange(n_v) * 2 * math.pi / n_v, indexing="ij")
    v = np.stack([(R + r * np.cos(w)) * np.cos(u), (R + r * np.cos(w)) * np.sin(u), r * np.sin(w)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_u), np.arange(n_v), indexing="ij")
    a, b = i * n_v + j, ((i + 1) % n_u) * n_v + j
    c, d = ((i + 1) % n_u) * n_v + (j + 1) % n_v, i * n_v + (j + 1) % n_v
    f = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return v, f


def _surfaces():
    rng = np.random.default_rng(5)
    v4, f4 = icosphere(4)
    wr = v4 * (1 + 0.04 * ps.sample("labyrinth", v4, rng, k=12))[:, None]  # a wrinkled vesicle
    c = v4[:, 0]
    pea = v4 * (1 + 0.25 * (35 * c**4 - 30 * c**2 + 3) / 8)[:, None] * np.array([1.6, 1.0, 1.0])  # dumbbell
    vq, fq = quasiuniform_sphere(3000, seed=2)
    return {"icosphere": (v4, f4), "quasiuniform": (vq, fq), "wrinkled": (wr, f4), "peanut": (pea, f4),
            "ellipsoid": (ellipsoid_from_sphere(v4, f4, axes=(1.4, 0.7, 1.0)), f4)}


SURFACES = _surfaces()


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_crest_defects_add_up_to_plus_two_on_every_closed_surface(name):
    """Every class of pattern at every scale, on spheres of both mesh families, a wrinkled vesicle, a dumbbell and
    an ellipsoid: the charges are multiples of 1/2 and their sum is +2."""
    v, f = SURFACES[name]
    rng = np.random.default_rng(1)
    x = v / np.linalg.norm(v, axis=1, keepdims=True)
    for cls in ps.CLASSES:
        h = ps.sample(cls, x, rng, k=11, noise=0.1)
        for sigma in (0.0, 0.3):
            co = crest_order(v, f, h, sigma)
            assert np.all(2 * co.charge == np.round(2 * co.charge))
            assert co.total_charge == 2.0, (cls, sigma, co.total_charge)
    assert co.n_defects >= 2


def test_on_a_torus_the_charges_add_up_to_zero():
    """The total is the surface's Euler characteristic, not a constant: 0 on a torus, with defects present."""
    v, f = _torus()
    rng = np.random.default_rng(2)
    for _ in range(3):
        h = rng.standard_normal(len(v))
        for sigma in (0.0, 0.03):  # tube radius 0.35: smoothing much more leaves no defect to count
            co = crest_order(v, f, h, sigma)
            assert co.total_charge == 0.0 and co.n_defects > 20


def _polar_field(v, k, axis):
    """Tangent line field e_theta cos(k psi) + e_psi sin(k psi) about ``axis``: index 1 + k at the north pole
    and 1 - k at the south pole (seen from outside)."""
    a = axis / np.linalg.norm(axis)
    b = np.cross(a, [0.3, 0.5, 0.8])
    b /= np.linalg.norm(b)
    c = np.cross(a, b)
    psi = np.arctan2(v @ c, v @ b)
    z = v @ a
    e_psi = np.outer(-np.sin(psi), b) + np.outer(np.cos(psi), c)
    e_theta = np.outer(z * np.cos(psi), b) + np.outer(z * np.sin(psi), c) - np.outer(np.sqrt(1 - z * z), a)
    return np.cos(k * psi)[:, None] * e_theta + np.sin(k * psi)[:, None] * e_psi, z


@pytest.mark.parametrize("k", [0.0, 0.5, -0.5, 1.0, -1.5])
def test_individual_defects_have_the_right_half_integer_charge(k):
    v, f = icosphere(4)
    axis = Rotation.random(random_state=3).as_matrix()[:, 2]
    t, z = _polar_field(v, k, axis)
    _, e1, e2 = tangent_frames(v, f)
    psi = np.arctan2(dot_rows(t, e2), dot_rows(t, e1))
    charge = line_field_index(v, f, psi)
    zf = z[f].mean(axis=1)
    assert charge[zf > 0.9].sum() == 1 + k
    assert charge[zf < -0.9].sum() == 1 - k
    assert np.all(charge[np.abs(zf) <= 0.9] == 0)


def test_a_linear_field_has_one_plus_one_defect_at_each_pole():
    """h = x . a: crests are the latitudes about a; the director is smooth except a bull's eye (+1) at each pole."""
    v, f = icosphere(4)
    a = np.array([0.2, -0.5, 0.84])
    a /= np.linalg.norm(a)
    co = crest_order(v, f, v @ a, 0.0)
    zf = (v[f].mean(axis=1)) @ a
    assert co.charge[zf > 0.9].sum() == 1 and co.charge[zf < -0.9].sum() == 1
    assert np.all(co.charge[np.abs(zf) <= 0.9] == 0)
    assert np.median(co.coherence) > 0.999


def test_gradient_of_a_linear_field_is_its_tangent_projection():
    v, f = icosphere(3)
    a = np.array([0.3, -0.2, 0.9])
    g = face_gradients(v, f, v @ a)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    expect = a - (n @ a)[:, None] * n
    assert np.max(np.abs(g - expect)) < 1e-12


def test_heat_smoothing_keeps_the_mean_and_damps_a_degree_l_mode_like_a_gaussian():
    """(M + t L)^-1 M multiplies Y_lm by 1 / (1 + t l (l + 1)) (t = sigma^2 / 2) and conserves the area mean."""
    v, f = icosphere(5)
    sm = HeatSmoother(v, f, 0.2)
    h = ps.random_isotropic_field(v, [6], np.random.default_rng(0))
    out = sm(h)
    assert abs((sm.mass * out).sum() - (sm.mass * h).sum()) < 1e-10
    ratio = (out @ (sm.mass * h)) / (h @ (sm.mass * h))
    assert ratio == pytest.approx(1 / (1 + 0.02 * 42), rel=0.01)


@pytest.mark.parametrize("level", [4, 5])
def test_crest_alignment_is_one_for_ripples_cos_2alpha_for_herringbone_and_small_for_labyrinth(level):
    v, f = icosphere(level)
    rng = np.random.default_rng(4)
    assert crest_alignment(v, f, ps.ripples(v, 13, rng))[0] > 0.95
    for alpha in (20.0, 30.0):
        P = crest_alignment(v, f, ps.herringbone(v, 13, rng, alpha_deg=alpha))[0]
        assert P == pytest.approx(math.cos(math.radians(2 * alpha)), abs=0.08)
    assert crest_alignment(v, f, ps.labyrinth(v, 13, rng))[0] < 0.35
    assert crest_alignment(v, f, ps.hexagons(v, 13, rng))[0] < 0.1


def test_coherence_sees_parallel_crests_but_not_hexagons():
    """Anisotropy a_2 of the local power spectrum at half a wavelength: high for ripples, low for hexagons."""
    v, f = icosphere(5)
    rng = np.random.default_rng(6)
    lam = 2 * math.pi / 13
    rip = crest_order(v, f, ps.ripples(v, 13, rng), 0.5 * lam).anisotropy
    hexa = crest_order(v, f, ps.hexagons(v, 13, rng), 0.5 * lam).anisotropy
    assert rip > 0.8 and hexa < 0.25
