"""The contour's spectrum (analysis/contour_spectrum.py): k_*, k_rms, up-crossings, crests, against exact patterns
and Rice's formula."""

import math

import numpy as np
import pytest

from vesicle_core.analysis.contour_spectrum import (
    contour_spectrum,
    ellipsoid_section_radius,
    mean_spectrum_k_rms,
    profile_spectrum,
    radius_on_rays,
)
from vesicle_core.analysis.section import main_section, plane
from vesicle_core.analysis.shape import fit_ellipsoid
from vesicle_core.errors import ConfigError
from vesicle_core.geometry import ylm as Yl
from vesicle_core.geometry.surface import resolvable_l_max

UNIT_SPHERE = (np.zeros(3), np.ones(3), np.eye(3))
EQUATOR = plane()
MERIDIAN = plane(normal=(0.0, 1.0, 0.0))




@pytest.mark.parametrize("l", [5, 8, 12])
def test_sectoral_mode_gives_k_l_and_l_crests_on_the_equator(perturbed, l):
    """Up to k_max = what the mesh resolves: above it sit the facets' own harmonics (without the cut, k_* reads
    5.05 / 8.04 / 12.07 on this mesh)."""
    v, f = perturbed(l, l)
    s = contour_spectrum(main_section(v, f, EQUATOR), EQUATOR, UNIT_SPHERE, k_max=resolvable_l_max(v, f))
    assert s.k_star == pytest.approx(l, rel=1e-3)
    assert s.k_rms == pytest.approx(l, rel=2e-3)
    assert s.up_crossings == l and s.crests == l
    assert s.star_shaped


def test_sectoral_mode_with_the_fitted_ellipsoid(perturbed):
    """The fitted ellipsoid of R (1 + eps Y_ll), l >= 3, is the sphere: the same answer through the fit."""
    v, f = perturbed(9, 9)
    s = contour_spectrum(main_section(v, f, EQUATOR), EQUATOR, fit_ellipsoid(v), k_max=resolvable_l_max(v, f))
    assert s.k_star == pytest.approx(9, rel=1e-3) and s.up_crossings == 9 and s.crests == 9


@pytest.mark.parametrize("l", [6, 9, 12])
def test_zonal_mode_shows_nothing_on_the_equator_and_l_on_a_meridian(perturbed, l):
    """Y_l0 is constant along the equator: a shifted circle, no crests, no crossings, no k_*. A meridian crosses
    its l nodal circles twice each: l up-crossings and about l crests."""
    v, f = perturbed(l, 0)
    k_max = resolvable_l_max(v, f)
    eq = contour_spectrum(main_section(v, f, EQUATOR), EQUATOR, UNIT_SPHERE, k_max=k_max)
    assert eq.crests == 0 and eq.up_crossings == 0 and math.isnan(eq.k_star)
    mer = contour_spectrum(main_section(v, f, MERIDIAN), MERIDIAN, UNIT_SPHERE, k_max=k_max)
    assert mer.up_crossings == l
    assert abs(mer.crests - l) <= 1
    assert 0.6 * l < mer.k_star < l


def _real_field_on_rotated_equators(l, n_fields, n_theta, rng):
    """h_i(phi) = Re sum_m a_m Y_lm(R_i e(phi)): isotropic Gaussian fields of degree l, each on the equator turned
    by a random rotation R_i. -> (n_fields, n_theta)."""
    from scipy.spatial.transform import Rotation

    phi = 2 * np.pi * np.arange(n_theta) / n_theta
    ring = np.stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)], axis=1)
    rot = Rotation.random(n_fields, random_state=rng).as_matrix()
    pts = np.einsum("nij,pj->npi", rot, ring)
    th = np.arccos(np.clip(pts[..., 2], -1, 1))
    ph = np.arctan2(pts[..., 1], pts[..., 0])
    out = np.empty((n_fields, n_theta))
    for rows in np.array_split(np.arange(n_fields), max(1, n_fields // 50)):
        Y = Yl.ylm(l, th[rows].ravel(), ph[rows].ravel())[l].reshape(2 * l + 1, len(rows), n_theta)
        a = rng.standard_normal((len(rows), 2 * l + 1)) + 1j * rng.standard_normal((len(rows), 2 * l + 1))
        out[rows] = np.einsum("fm,mfp->fp", a, Y).real
    return phi, out


@pytest.mark.parametrize("l", [8, 16])
def test_rice_formula_over_random_isotropic_fields(l):
    """Over rotated isotropic fields of degree l (standard error <= 1.5 %): the ensemble k_rms^2 is l (l + 1) / 2
    and the mean number of up-crossings is sqrt(l (l + 1) / 2), within 5 %. Counting local maxima (~0.87 l) or
    reporting l instead fails the same 5 % test."""
    rng = np.random.default_rng(50 + l)
    n_fields = 900
    phi, H = _real_field_on_rotated_equators(l, n_fields, 256, rng)
    res = [profile_spectrum(phi, h) for h in H]
    P = np.array([r.power for r in res])
    k = np.arange(P.shape[1])
    target_k2 = l * (l + 1) / 2
    target_up = math.sqrt(target_k2)

    k2 = mean_spectrum_k_rms(P) ** 2
    X, Y = (k**2 * P).sum(axis=1), P.sum(axis=1)  # delta-method error of the ratio of means
    se_k2 = np.std(X / X.mean() - Y / Y.mean()) / math.sqrt(n_fields)
    assert se_k2 <= 0.015
    assert abs(k2 / target_k2 - 1) < 0.05, k2 / target_k2

    up = np.array([r.up_crossings for r in res], float)
    se_up = up.std() / math.sqrt(n_fields) / up.mean()
    assert se_up <= 0.015
    assert abs(up.mean() / target_up - 1) < 0.05, up.mean() / target_up

    crests = np.array([r.crests for r in res], float)
    assert abs(crests.mean() / target_up - 1) > 0.05  # maxima are not crossings: about 0.87 l, not 0.71 l
    assert abs(l / target_up - 1) > 0.05  # nor is l


def test_radius_on_rays_is_exact_and_sees_folds():
    square = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    theta = np.array([0.0, np.pi / 4, np.pi / 2, 1.0])
    r, star = radius_on_rays(square, (0.0, 0.0), theta)
    assert np.allclose(r, [1.0, math.sqrt(2), 1.0, 1 / math.cos(1.0 - np.pi / 2)]) and star
    # a spiral-like fold: a ray meets the contour three times; the outermost crossing is kept
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    rr = 1.0 + 0.5 * np.sin(t)
    fold = np.stack([rr * np.cos(t + 0.9 * np.sin(3 * t)), rr * np.sin(t + 0.9 * np.sin(3 * t))], axis=1)
    _, star = radius_on_rays(fold, (0.0, 0.0), np.linspace(0, 2 * np.pi, 64, endpoint=False))
    assert not star
    with pytest.raises(ConfigError, match="outside"):
        radius_on_rays(square, (3.0, 0.0), theta)


def test_ellipsoid_section_radius_is_the_ellipse():
    rot = np.eye(3)
    ell = (np.array([0.1, -0.2, 0.05]), np.array([1.5, 0.8, 1.1]), rot)
    theta = np.linspace(0, 2 * np.pi, 7)
    pl = plane(offset=0.05)
    centre = pl.to_plane(ell[0][None])[0]
    rho = ellipsoid_section_radius(pl, ell, centre, theta)
    a, b = 1.5, 0.8  # the plane z = 0.05 passes through the centre: the section has the full semi-axes
    assert np.allclose(rho, 1 / np.sqrt((np.cos(theta) / a) ** 2 + (np.sin(theta) / b) ** 2))


def test_bad_input_is_named():
    with pytest.raises(ConfigError, match="n_theta"):
        profile_spectrum(np.arange(15.0), np.zeros(15))
    with pytest.raises(ConfigError, match="resolution"):
        profile_spectrum(np.arange(16.0), np.zeros(16), resolution=-1.0)
