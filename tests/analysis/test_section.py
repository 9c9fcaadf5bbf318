"""The exact section of a triangulated membrane by a plane (analysis/section.py)."""

import numpy as np
import pytest

from vesicle_core.analysis.section import main_section, plane, section
from vesicle_core.errors import ConfigError, MeshError
from vesicle_core.geometry.mesh import ellipsoid_from_sphere, icosphere

PLANES = [dict(), dict(offset=0.3), dict(normal=(1.0, 1.0, 0.3), offset=-0.2)]


def _exact_radius(pl):
    return np.sqrt(1.0 - float(pl.origin @ pl.normal) ** 2)


@pytest.mark.parametrize("kw", PLANES)
def test_sphere_section_radius_converges_at_second_order(kw):
    """The polygon's vertices lie on chords of the sphere, so its mean radius falls short by O(h^2): the error
    shrinks 4x per icosphere level (the edge halves). Measured slopes of log error against log edge, levels 2-6:
    1.99 / 1.94 / 1.99 (mean radius), 1.99 / 1.91 / 1.98 (largest error); a first-order slicer would give 1."""
    pl = plane(**kw)
    mean_err, max_err, edge = [], [], []
    for level in range(2, 7):
        c = main_section(*icosphere(level), pl)
        centre = pl.to_plane(np.zeros((1, 3)))[0]
        r = np.linalg.norm(c.uv - centre, axis=1)
        mean_err.append(abs(r.mean() - _exact_radius(pl)))
        max_err.append(np.abs(r - _exact_radius(pl)).max())
        edge.append(2.0**-level)
    for err in (mean_err, max_err):
        order = np.polyfit(np.log(edge), np.log(err), 1)[0]
        assert abs(order - 2.0) < 0.15, order
    assert max_err[-1] < 6e-5  # h^2 / 8 at level 6 (h = 0.0205): 5.3e-5


def test_orientation_is_counter_clockwise_about_the_normal():
    v, f = icosphere(3)
    for kw in PLANES:
        pl = plane(**kw)
        c = main_section(v, f, pl)
        assert c.area() > 0
        # and the basis is right-handed: e1 x e2 = normal
        assert np.allclose(np.cross(pl.e1, pl.e2), pl.normal)
    flipped = plane(normal=(0, 0, -1))
    assert main_section(v, f, flipped).area() > 0


def test_default_plane_is_the_flows_plane():
    pl = plane()
    assert np.allclose(pl.normal, [0, 0, 1]) and np.allclose(pl.e1, [1, 0, 0]) and np.allclose(pl.e2, [0, 1, 0])


def test_vertices_on_the_plane_give_one_clean_loop():
    """The icosphere has vertices exactly on z = 0: every point stays on the circle, none repeats."""
    v, f = icosphere(3)
    assert np.sum(np.abs(v[:, 2]) < 1e-15) > 0
    c = main_section(v, f)
    steps = np.linalg.norm(np.roll(c.uv, -1, axis=0) - c.uv, axis=1)
    assert steps.min() > 1e-6
    assert np.all(np.linalg.norm(c.uv, axis=1) <= 1.0 + 1e-12)


def test_ellipsoid_section_is_the_ellipse():
    v0, f = icosphere(5)
    v = ellipsoid_from_sphere(v0, f, axes=(1.4, 0.7, 1.0), R=1.0)
    c = main_section(v, f)
    a, b = np.ptp(c.uv[:, 0]) / 2, np.ptp(c.uv[:, 1]) / 2
    # the area of the section, against pi a b of the ellipse through the vertices' extent
    assert abs(c.area() / (np.pi * a * b) - 1) < 2e-3
    assert b / a == pytest.approx(0.5, rel=2e-3)


def test_two_loops_and_a_miss():
    """A plane through two bodies gives two loops, the longest first; a plane above the sphere gives none."""
    v, f = icosphere(4)
    assert section(v, f, plane(offset=1.5)) == []
    # two spheres as one (non-connected) surface: the plane cuts each once
    v2 = np.concatenate([v - [2.0, 0, 0], 0.5 * v + [2.0, 0, 0]])
    f2 = np.concatenate([f, f + len(v)])
    cs = section(v2, f2, plane(offset=0.1))
    assert len(cs) == 2
    assert [round(float(c.centroid()[0])) for c in cs] == [-2, 2]


def test_bad_input_is_named():
    v, f = icosphere(1)
    with pytest.raises(ConfigError, match="normal"):
        plane(normal=(0, 0, 0))
    with pytest.raises(MeshError):
        section(v[:, :2], f)
    with pytest.raises(MeshError, match="closed"):
        section(v, f[:-1], plane(offset=0.05, normal=(0.1, 0.2, 1)))
    with pytest.raises(MeshError, match="does not cut"):
        main_section(v, f, plane(offset=3.0))


@pytest.mark.parametrize("kw", PLANES[1:] + [dict(normal=(0.3, -1.0, 0.2), offset=0.55)])
def test_agrees_with_trimesh(kw):
    trimesh = pytest.importorskip("trimesh")
    from scipy.spatial import cKDTree

    v, f = icosphere(4)
    v = v * (1.0 + 0.1 * np.sin(5 * v[:, :1]) * np.cos(3 * v[:, 1:2]))
    pl = plane(**kw)
    ours = section(v, f, pl)
    segs = trimesh.intersections.mesh_plane(trimesh.Trimesh(v, f, process=False), pl.normal, pl.origin)
    theirs = segs.reshape(-1, 3)
    mine = np.concatenate([c.points for c in ours])
    assert cKDTree(theirs).query(mine)[0].max() < 1e-12
    assert cKDTree(mine).query(theirs)[0].max() < 1e-12
    length = np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1).sum()
    assert sum(c.length() for c in ours) == pytest.approx(length, rel=1e-12)
