"""Grid, spreading (eq. 28) and interpolation (eqs. 16, 29) with the 4-point kernel (26)-(27)."""

import numpy as np
import pytest

from vesicle_core.errors import ConfigError
from vesicle_core.solver.backend import get_backend
from vesicle_core.solver.ibm import Coupler, Grid, Spreader, interpolate, prepare, spread
from vesicle_core.solver.kernels import phi


@pytest.fixture(scope="module")
def be():
    return get_backend("numpy")


def _points(rng, M, L, margin=0.0):
    return rng.uniform(-L / 2 + margin, L / 2 - margin, (M, 3))


# ------------------------------------------------------------------ Grid
def test_grid_properties():
    g = Grid(16, 4.0)
    assert g.h == 0.25 and g.origin == -2.0
    assert g.shape == (16, 16, 16) and g.field_shape == (3, 16, 16, 16)
    assert g.spectral_shape == (16, 16, 9)
    np.testing.assert_allclose(g.axis_coords()[[0, -1]], [-2.0, 2.0 - 0.25])
    assert g.cell_volume == pytest.approx(0.25**3)


@pytest.mark.parametrize("N, L", [(7, 1.0), (9, 1.0), (6, 1.0), (16.5, 1.0), (16, 0.0), (16, -1.0)])
def test_grid_validation(N, L):
    with pytest.raises(ConfigError):
        Grid(N, L)


# ------------------------------------------------------------------ stencil
def test_prepare_matches_tensor_product_of_phi(be):
    g = Grid(16, 4.0)
    rng = np.random.default_rng(0)
    X = _points(rng, 7, g.L)
    st = prepare(X, g, be)
    assert st.idx.shape == (7, 64) and st.w.shape == (7, 64)
    np.testing.assert_allclose(st.w.sum(axis=1), 1.0, rtol=0, atol=1e-14)
    # brute force: the weight of node m is prod_j phi((X_j - x_m_j)/h) (periodic distance)
    x = g.axis_coords()
    for k in range(7):
        dense = np.zeros(g.shape)
        d = [(X[k, a] - x + g.L / 2) % g.L - g.L / 2 for a in range(3)]
        w1 = [phi(di / g.h) for di in d]
        dense = w1[0][:, None, None] * w1[1][None, :, None] * w1[2][None, None, :]
        got = np.zeros(g.N**3)
        np.add.at(got, st.idx[k], st.w[k])
        np.testing.assert_allclose(got.reshape(g.shape), dense, atol=1e-15)


def test_prepare_rejects_bad_shapes(be):
    g = Grid(8, 1.0)
    with pytest.raises(ConfigError):
        prepare(np.zeros((5, 2)), g, be)
    st = prepare(np.zeros((5, 3)), g, be)
    with pytest.raises(ConfigError):
        spread(np.zeros((4, 3)), st, g, be)
    with pytest.raises(ConfigError):
        interpolate(np.zeros((3, 8, 8, 4)), st, be)


# ------------------------------------------------------------------ spreading
def test_spreading_conserves_total_force(be):
    g = Grid(32, 5.0)
    rng = np.random.default_rng(1)
    X = _points(rng, 500, g.L)  # includes points whose stencil wraps around the box
    X[:5] = [[-2.5, -2.5, -2.5], [2.49, 2.49, 2.49], [0, 0, 2.499], [-2.5, 0.1, 0], [1e-12, 0, 0]]
    F = rng.standard_normal((500, 3))
    st = prepare(X, g, be)
    f = spread(F, st, g, be)
    assert f.shape == (3, 32, 32, 32) and f.dtype == np.float64
    total = f.sum(axis=(1, 2, 3)) * g.h**3
    np.testing.assert_allclose(total, F.sum(axis=0), rtol=0, atol=1e-11 * np.abs(F).sum())
    # first moment (torque-free kernels reproduce it away from the wrap-around)
    Xc = _points(rng, 50, g.L, margin=0.5)
    Fc = rng.standard_normal((50, 3))
    fc = spread(Fc, prepare(Xc, g, be), g, be)
    x = g.axis_coords()
    mom = np.einsum("cijk,i->c", fc, x) * g.h**3
    np.testing.assert_allclose(mom, (Xc[:, 0:1] * Fc).sum(axis=0), atol=1e-11)


def test_spreader_reuse_equals_fresh_spread(be):
    g = Grid(16, 4.0)
    rng = np.random.default_rng(2)
    sp = Spreader(g, be)
    for _ in range(3):
        X = _points(rng, 40, g.L)
        F = rng.standard_normal((40, 3))
        st = prepare(X, g, be)
        np.testing.assert_allclose(sp.spread(F, st), spread(F, st, g, be), atol=1e-13)
    out = np.full(g.field_shape, 7.0)
    np.testing.assert_allclose(spread(F, st, g, be, out=out), spread(F, st, g, be), atol=1e-13)


# ------------------------------------------------------------------ interpolation
def test_interpolation_reproduces_constants_exactly(be):
    g = Grid(16, 3.0)
    rng = np.random.default_rng(3)
    X = _points(rng, 200, g.L)
    u = np.empty(g.field_shape)
    u[0], u[1], u[2] = 1.5, -2.0, 0.25
    U = interpolate(u, prepare(X, g, be), be)
    np.testing.assert_allclose(U, np.tile([1.5, -2.0, 0.25], (200, 1)), rtol=0, atol=1e-14)


def test_interpolation_reproduces_linear_fields_away_from_wrap(be):
    g = Grid(32, 4.0)
    rng = np.random.default_rng(4)
    X = _points(rng, 300, g.L, margin=3 * g.h)  # stencil does not reach the periodic seam
    x = g.axis_coords()
    xx, yy, zz = np.meshgrid(x, x, x, indexing="ij")
    A = rng.standard_normal((3, 3))
    b = rng.standard_normal(3)
    u = np.stack([A[c, 0] * xx + A[c, 1] * yy + A[c, 2] * zz + b[c] for c in range(3)])
    U = interpolate(u, prepare(X, g, be), be)
    np.testing.assert_allclose(U, X @ A.T + b, rtol=0, atol=1e-12)
    # ... and it must fail where the stencil straddles the seam (the test can tell)
    Xs = np.array([[g.L / 2 - 0.5 * g.h, 0.0, 0.0]])
    Us = interpolate(u, prepare(Xs, g, be), be)
    assert np.abs(Us - (Xs @ A.T + b)).max() > 0.1


def test_spread_interpolate_adjoint(be):
    g = Grid(16, 2.0)
    rng = np.random.default_rng(5)
    X = _points(rng, 100, g.L)
    F = rng.standard_normal((100, 3))
    u = rng.standard_normal(g.field_shape)
    st = prepare(X, g, be)
    lhs = np.sum(spread(F, st, g, be) * u) * g.h**3  # <S F, u> h^3
    rhs = np.sum(F * interpolate(u, st, be))  # <F, J u>
    assert abs(lhs - rhs) <= 1e-13 * (abs(lhs) + np.abs(F).sum())


def test_float32_coupling():
    be32 = get_backend(dtype="float32")
    be64 = get_backend()
    g = Grid(16, 2.0)
    rng = np.random.default_rng(6)
    X = _points(rng, 50, g.L)
    F = rng.standard_normal((50, 3))
    f32 = spread(F, prepare(X, g, be32), g, be32)
    f64 = spread(F, prepare(X, g, be64), g, be64)
    assert f32.dtype == np.float32
    np.testing.assert_allclose(f32, f64, rtol=1e-5, atol=1e-5 * np.abs(f64).max())
    u = rng.standard_normal(g.field_shape).astype(np.float32)
    U = interpolate(u, prepare(X, g, be32), be32)
    assert U.dtype == np.float32


def test_coupler_reuses_buffers_and_matches_functional_api(be):
    g = Grid(16, 4.0)
    rng = np.random.default_rng(7)
    cp = Coupler(g, be)
    ids = None
    for _ in range(3):
        X = _points(rng, 60, g.L)
        F = rng.standard_normal((60, 3))
        u = rng.standard_normal(g.field_shape)
        st = cp.prepare(X)
        if ids is not None:
            assert (id(st.idx), id(st.w)) == ids  # refilled in place
        ids = (id(st.idx), id(st.w))
        ref = prepare(X, g, be)
        np.testing.assert_array_equal(st.idx, ref.idx)
        np.testing.assert_array_equal(st.w, ref.w)
        # the spread buffer is cleared correctly although the stencil was overwritten in place
        np.testing.assert_allclose(cp.spread(F), spread(F, ref, g, be), atol=1e-13)
        np.testing.assert_allclose(cp.interpolate(u), interpolate(u, ref, be), atol=1e-14)
    # a different number of points gets fresh arrays
    st = cp.prepare(_points(rng, 10, g.L))
    assert st.idx.shape == (10, 64)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_compiled_spread_is_bitwise_the_numpy_scatter(dtype, monkeypatch):
    """The numba scatter and sparse clear (ibm._compiled_scatter, _compiled_zero) add in np.add.at's order and
    precision: the same grid bit for bit, also on the second call (the sparse clear of the first call's nodes) and
    with another number of points."""
    pytest.importorskip("numba")
    from vesicle_core.solver import ibm as ibm_mod

    be, g = get_backend("numpy", dtype), Grid(16, 5.0)
    rng = np.random.default_rng(4)
    calls = [(rng.uniform(-2.5, 2.5, (n, 3)), rng.standard_normal((n, 3))) for n in (40, 40, 25)]
    fast, plain = Coupler(g, be), Coupler(g, be)
    assert ibm_mod._compiled_scatter() is not None
    for X, F in calls:
        fast.prepare(X)
        a = fast.spread(F).copy()
        with monkeypatch.context() as m:
            m.setattr(ibm_mod, "_compiled_scatter", lambda: None)
            m.setattr(ibm_mod, "_compiled_zero", lambda: None)
            plain.prepare(X)
            b = plain.spread(F).copy()
        assert a.dtype == np.dtype(dtype)
        np.testing.assert_array_equal(a, b)
        assert np.abs(a).sum() > 0
