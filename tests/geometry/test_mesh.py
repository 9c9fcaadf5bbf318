import math
from itertools import pairwise

import numpy as np
import pytest

from vesicle_core.errors import ConfigError, MeshError
from vesicle_core.geometry import mesh as M
from vesicle_core.geometry import surface as Sf

FAMILIES = [("icosphere", dict(level=3)), ("quasiuniform", dict(n_vertices=700, seed=3))]


@pytest.mark.parametrize("level", range(0, 5))
def test_icosphere_topology(level):
    v, f = M.icosphere(level)
    assert len(v) == 10 * 4**level + 2 and len(f) == 20 * 4**level
    M.check_closed_surface(v, f)
    E = len(M.unique_edges(f))
    assert len(v) - E + len(f) == 2
    assert np.allclose(np.linalg.norm(v, axis=1), 1.0)


@pytest.mark.parametrize("family, kw", FAMILIES)
def test_family_closed_oriented_and_scaled(family, kw):
    m = M.make_vesicle(family, axes=(1.0, 0.8, 1.0), R=2.5, **kw)
    M.check_closed_surface(m.vertices, m.faces)
    assert m.volume() == pytest.approx(4.0 / 3.0 * math.pi * 2.5**3, rel=1e-12)
    assert m.equivalent_radius() == pytest.approx(2.5)
    # outward: every face normal points away from the centre on this convex body
    a = Sf.face_area_vectors(m.vertices, m.faces)
    assert np.all(np.einsum("ij,ij->i", a, m.vertices[m.faces].mean(1)) > 0)
    # axes ratio is preserved by the uniform rescaling
    ext = m.vertices.max(0) - m.vertices.min(0)
    assert ext[1] / ext[0] == pytest.approx(0.8, rel=0.02)


def test_paper_ellipsoid_delta_at_fine_level():
    m = M.make_vesicle("icosphere", level=5, axes=(1.0, 0.8, 1.0))
    assert m.excess_area() == pytest.approx(0.116, abs=0.003)
    # the faceting adds area of its own: coarse meshes overestimate Delta
    assert M.make_vesicle("icosphere", level=2).excess_area() > 0.15


def test_target_delta_solves_axes():
    m = M.make_vesicle("icosphere", level=4, target_delta=0.997)
    assert m.excess_area() == pytest.approx(0.997, abs=1e-9)
    assert m.attrs["axes_b"] < 0.8
    with pytest.raises(ConfigError, match="below this mesh"):
        M.make_vesicle("icosphere", level=1, target_delta=0.01)


def test_excess_area_of_sphere_tends_to_zero():
    d = [M.make_vesicle("icosphere", level=L, axes=(1, 1, 1)).excess_area() for L in (2, 3, 4, 5)]
    assert all(x > y > 0 for x, y in pairwise(d))
    assert d[-1] < 0.01


def test_quality_report_and_seed_recorded():
    q = M.make_vesicle("icosphere", level=3).quality()
    assert q["edge_min"] <= q["edge_mean"] <= q["edge_max"]
    assert 1.0 <= q["aspect_mean"] <= q["aspect_max"] < 2
    assert q["angle_min_deg"] > 30
    a = M.make_vesicle("quasiuniform", n_vertices=500, seed=7)
    b = M.make_vesicle("quasiuniform", n_vertices=500, seed=7)
    assert a.attrs["seed"] == 7 and np.array_equal(a.vertices, b.vertices)
    assert len(a.vertices) == 500


def test_netcdf_round_trip(tmp_path):
    m = M.make_vesicle("icosphere", level=3, target_delta=0.2)
    p = tmp_path / "m.nc"
    M.save(m, p)
    r = M.load(p)
    assert np.array_equal(r.vertices, m.vertices) and np.array_equal(r.faces, m.faces)
    assert r.attrs["delta"] == pytest.approx(m.attrs["delta"])
    assert r.attrs["family"] == "icosphere"
    assert not [x for x in tmp_path.iterdir() if x.name != "m.nc"]  # no temp file left


def test_invalid_meshes_rejected(tmp_path):
    v, f = M.icosphere(1)
    with pytest.raises(MeshError, match="not closed"):
        M.check_closed_surface(v, f[:-1])
    with pytest.raises(MeshError, match="oriented"):
        M.check_closed_surface(v, np.vstack([f[:-1], f[-1:, [0, 2, 1]]]))
    with pytest.raises(MeshError, match="inward"):
        M.check_closed_surface(v, f[:, [0, 2, 1]])
    with pytest.raises(MeshError, match="does not exist"):
        M.load(tmp_path / "missing.nc")
    (tmp_path / "junk.nc").write_text("not netcdf")
    with pytest.raises(MeshError, match="junk.nc"):
        M.load(tmp_path / "junk.nc")


@pytest.mark.parametrize(
    "kw, name",
    [(dict(R=-1.0), "radius"), (dict(axes=(1, 0, 1)), "axes"), (dict(level=-1), "level"), (dict(level=12), "level"),
     (dict(family="cube"), "family")],
)
def test_bad_arguments(kw, name):
    with pytest.raises(ConfigError, match=name):
        M.make_vesicle(**kw)
