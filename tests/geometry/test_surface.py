"""The second-order area change of a displacement (geometry.surface.triangle_area_nonlinear), checked against exact
area changes: a dilation, a rigid motion, and the dt^2 scaling of a random displacement."""

import numpy as np

from vesicle_core.geometry import mesh as Mm
from vesicle_core.geometry.surface import triangle_area_nonlinear, triangle_areas


def _mesh():
    m = Mm.make_vesicle("quasiuniform", n_vertices=162, axes=(1.0, 0.8, 1.0))
    return m.vertices, m.faces


def test_a_dilation_changes_each_area_by_eps_squared_beyond_first_order():
    """X -> (1 + eps) X scales every area by (1 + eps)^2 = 1 + 2 eps + eps^2: the part beyond first order is eps^2 A."""
    X, f = _mesh()
    A = triangle_areas(X, f)
    for eps in (1e-1, 1e-3):
        np.testing.assert_allclose(triangle_area_nonlinear(X, f, eps * X), eps**2 * A, rtol=1e-6, atol=1e-15)


def test_a_rigid_motion_has_no_nonlinear_area_change():
    """A translation changes no area at any order. A finite rotation keeps every area, but its displacement
    (R - I) X is not area-preserving at first order: the nonlinear part must cancel the linear one exactly."""
    X, f = _mesh()
    A = triangle_areas(X, f)
    np.testing.assert_allclose(triangle_area_nonlinear(X, f, np.tile([0.3, -0.2, 0.1], (len(X), 1))), 0.0,
                               atol=1e-14)
    th = 0.2
    R = np.array([[np.cos(th), -np.sin(th), 0.0], [np.sin(th), np.cos(th), 0.0], [0.0, 0.0, 1.0]])
    d = X @ R.T - X
    # the linear part alone, by a symmetric finite difference of the area along d
    lin = (triangle_areas(X + 1e-6 * d, f) - triangle_areas(X - 1e-6 * d, f)) / 2e-6
    nl = triangle_area_nonlinear(X, f, d)
    assert np.abs(nl).max() > 1e-3 * A.max()  # 1 - cos(0.2) = 0.02: far above the check's tolerance
    np.testing.assert_allclose(lin + nl, 0.0, atol=1e-9 * A.max())  # the finite difference's round-off


def test_a_random_displacement_is_second_order_and_matches_the_exact_change():
    """For d random, n(eps d) / eps^2 tends to a constant (falls 4x per halving of eps), and the linear part it
    removes is the area's derivative (finite differences)."""
    X, f = _mesh()
    d = np.random.default_rng(3).standard_normal(X.shape) * 0.01
    n = [triangle_area_nonlinear(X, f, e * d) for e in (1.0, 0.5, 0.25)]
    for a, b in zip(n[:-1], n[1:], strict=True):
        big = np.abs(a) > 1e-3 * np.abs(a).max()
        r = a[big] / b[big]
        assert np.median(r) > 3.9 and np.median(r) < 4.1
    lin = (triangle_areas(X + 1e-6 * d, f) - triangle_areas(X - 1e-6 * d, f)) / 2e-6
    exact = triangle_areas(X + d, f) - triangle_areas(X, f)
    np.testing.assert_allclose(exact - lin, n[0], atol=1e-9 * triangle_areas(X, f).max())
