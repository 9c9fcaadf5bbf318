"""The virtual microscope's image and the contour read back from it (analysis/micrograph.py)."""

import math

import numpy as np
import pytest

from vesicle_core.analysis.contour_spectrum import profile_spectrum, radius_on_rays
from vesicle_core.analysis.micrograph import Optics, normal_contour, radial_contour, render
from vesicle_core.analysis.section import main_section, plane
from vesicle_core.errors import ConfigError
from vesicle_core.geometry.mesh import icosphere

R_UM = 18.0  # the elongated vesicles' radius (Sec. V)
UNIT_SPHERE = (np.zeros(3), np.ones(3), np.eye(3))
THETA = 2 * np.pi * np.arange(512) / 512


@pytest.fixture(scope="module")
def sphere(ylm_sphere):
    return ylm_sphere


def _image_and_section(v, f, where=None):
    where = plane() if where is None else where
    img = render(v, f, where, Optics(), length_um=R_UM, half_width=1.15)
    r_sec, _ = radius_on_rays(main_section(v, f, where).uv, (0.0, 0.0), THETA)
    return img, r_sec


def test_default_optics_are_a_40x_phase_contrast_objective():
    o = Optics()
    assert o.pixel_um == pytest.approx(0.16125)
    assert 0.5 <= o.depth_of_field_um <= 1.8  # the range for 40x-63x objectives
    assert o.psf_sigma_um / o.pixel_um == pytest.approx(0.955, abs=0.01)  # the PSF spans about a pixel
    # wrinkles of l = 12-24 at R = 18 um have wavelengths 4.7-9.4 um, several depths of field
    assert 2 * math.pi * R_UM / 24 > 3 * o.depth_of_field_um


def test_bad_optics_are_named():
    with pytest.raises(ConfigError, match="numerical_aperture"):
        Optics(numerical_aperture=1.2)  # a dry objective cannot exceed NA 1
    with pytest.raises(ConfigError, match="magnification"):
        Optics(magnification=0.0)


@pytest.mark.parametrize("case", ["sphere", "Y_12,12", "Y_20,20"])
def test_image_contour_matches_the_exact_section_within_a_tenth_of_a_pixel(sphere, perturbed, case):
    """Both detectors, against the exact section, at the default optics and R = 18 um (measured: 0.061, 0.059,
    0.066 px rms; most of it a 0.05 px inward shift, the sag of the in-focus band of a sphere, z^2 / 2R)."""
    v, f = (sphere[0], sphere[1]) if case == "sphere" else perturbed(*(2 * [int(case[2:4])]))
    img, r_sec = _image_and_section(v, f)
    r_rad = radial_contour(img, (0.0, 0.0), THETA, 0.7, 1.3)
    r_nor, _ = radius_on_rays(normal_contour(img, plane(), UNIT_SPHERE, n_points=512).uv, (0.0, 0.0), THETA)
    for r in (r_rad, r_nor):
        assert np.sqrt(np.mean((r - r_sec) ** 2)) / img.pixel < 0.1


@pytest.mark.parametrize("offset", [0.1, 0.5])
def test_a_focus_off_the_equator_images_that_section(sphere, offset):
    img, r_sec = _image_and_section(sphere[0], sphere[1], plane(offset=offset))
    r = radial_contour(img, (0.0, 0.0), THETA, 0.5, 1.3)
    assert np.sqrt(np.mean((r - r_sec) ** 2)) / img.pixel < 0.1
    assert r.mean() == pytest.approx(math.sqrt(1 - offset**2), abs=0.2 * img.pixel)


def test_crests_parallel_to_the_focal_plane_shift_the_outline_without_undulating_it(sphere, perturbed):
    """R (1 + eps Y_12,0): at the equator a crest runs around the vesicle, parallel to the focal plane. The
    outline moves out by most of the crest's height (0.40 px of the section's 0.48 px) and stays a circle: no
    crest, no crossing, wrinkles no larger than on the plain sphere's image. Y_12,12 (crests across the focal
    plane) undulates with k_* = 12 and 12 crests."""
    resolution = 0.25 * Optics().pixel_um / R_UM
    img0, _ = _image_and_section(sphere[0], sphere[1])
    base = radial_contour(img0, (0.0, 0.0), THETA, 0.7, 1.3)
    img, r_sec = _image_and_section(*perturbed(12, 0))
    r = radial_contour(img, (0.0, 0.0), THETA, 0.7, 1.3)
    shift = (r.mean() - base.mean()) / img.pixel
    assert shift > 0.3 and abs(shift - (r_sec.mean() - 1.0) / img.pixel) < 0.15
    s = profile_spectrum(THETA, r - 1.0, resolution=resolution)
    s0 = profile_spectrum(THETA, base - 1.0, resolution=resolution)
    assert s.crests == 0 and s.up_crossings == 0 and math.isnan(s.k_star)
    assert s.wrinkle_rms < 1.2 * s0.wrinkle_rms and s.wrinkle_rms < 0.05 * img.pixel

    img, _ = _image_and_section(*perturbed(12, 12))
    s = profile_spectrum(THETA, radial_contour(img, (0.0, 0.0), THETA, 0.7, 1.3) - 1.0, resolution=resolution)
    assert s.k_star == pytest.approx(12, rel=0.05) and s.crests == 12 and s.up_crossings == 12


def test_image_is_dark_on_the_outline_and_blank_off_the_membrane(sphere):
    img = render(sphere[0], sphere[1], plane(offset=2.0), Optics(), length_um=R_UM, half_width=1.0)
    assert np.all(img.pixels == 1.0)
    img, _ = _image_and_section(sphere[0], sphere[1])
    c = img.pixels.shape[0] // 2
    assert img.pixels[c, c] == pytest.approx(1.0, abs=1e-3)  # the vesicle's inside, far from the focal band
    ring = img.to_pixels(np.array([[1.0, 0.0]]))[0]
    assert img.pixels[int(round(ring[1])), int(round(ring[0]))] < 0.6


def test_normal_profiles_follow_a_peanut_whose_waist_rays_cross_three_times():
    """A dumbbell of revolution (lobes along x, a waist 15 % as thick) is not star-shaped about its centre: some
    rays from the centre cross its outline three times, so r(theta) cannot describe it. The profiles along the
    normals of the fitted ellipsoid's section cross it once each and trace it all (measured: 0.15 px rms, 0.36 px
    at most from the exact section; the waist's curvature radius is ~0.1 R there)."""
    from scipy.spatial import cKDTree

    from vesicle_core.analysis.shape import fit_ellipsoid

    v, f = icosphere(5)
    x = 2.0 * v[:, 0]
    w = 1 - 0.85 * np.exp(-((x / 0.5) ** 2))
    p = np.stack([x, 0.8 * v[:, 1] * w, 0.8 * v[:, 2] * w], axis=1)
    section = main_section(p, f, plane())
    _, star = radius_on_rays(section.uv, (0.0, 0.0), THETA)
    assert not star
    img = render(p, f, plane(), Optics(), length_um=R_UM, half_width=2.2)
    traced = normal_contour(img, plane(), fit_ellipsoid(p), n_points=1024, search=0.7).uv
    t = np.linspace(0, 1, 50, endpoint=False)[None, :, None]
    dense = (section.uv[:, None, :] + t * (np.roll(section.uv, -1, axis=0) - section.uv)[:, None, :]).reshape(-1, 2)
    to_section = cKDTree(dense).query(traced)[0] / img.pixel
    to_traced = cKDTree(traced).query(section.uv)[0] / img.pixel
    assert np.sqrt(np.mean(to_section**2)) < 0.2 and to_section.max() < 0.5
    # and nothing of the outline is missed: every section vertex lies near a traced point (1024 points on a
    # perimeter of ~9 R are ~0.05 R = 6 px apart)
    assert to_traced.max() < 0.06 / img.pixel
