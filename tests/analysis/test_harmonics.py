"""Spherical-harmonic analysis (eqs. 10, 30-32): conventions, recovery of injected modes, invariances, excess
area, ellipsoid fit and wrinkle amplitude. Measured values quoted in comments are from a level-5 icosphere."""

import math
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.special import sph_harm_y

from vesicle_core.analysis import harmonics as H
from vesicle_core.analysis import shape as Sh
from vesicle_core.errors import ConfigError
from vesicle_core.geometry import mesh as M
from vesicle_core.geometry import surface as Sf
from vesicle_core.geometry import ylm as Yl


@pytest.fixture(scope="module")
def sphere5():
    v, f = M.icosphere(5)
    theta = np.arccos(np.clip(v[:, 2], -1, 1))
    phi = np.arctan2(v[:, 1], v[:, 0])
    return v, f, theta, phi


def _mode(l, m, part, theta, phi):
    y = sph_harm_y(l, m, theta, phi)
    return y.real if part == "re" else y.imag


def _expected(l, m, part, eps, L):
    """Coefficients c_lm of eps * Re/Im Y_lm: Re Y = (Y_lm + (-1)^m Y_l-m)/2, Im Y = (Y_lm - (-1)^m Y_l-m)/(2i)."""
    c = np.zeros((L + 1, 2 * L + 1), complex)
    if m == 0:
        c[l, L] = eps
    elif part == "re":
        c[l, L + m], c[l, L - m] = eps / 2, (-1) ** m * eps / 2
    else:
        c[l, L + m], c[l, L - m] = -0.5j * eps, (-1) ** m * 0.5j * eps
    return c


def _unscaled(u, delta):
    return u / H.scale_factors(u.shape[0] - 1, delta)[:, None]


# --------------------------------------------------------------------------- conventions
def test_ylm_matches_scipy_and_symmetry():
    rng = np.random.default_rng(0)
    th, ph = rng.uniform(0, np.pi, 64), rng.uniform(-np.pi, np.pi, 64)
    L = 24
    Y = Yl.ylm(L, th, ph)
    err = max(np.abs(Y[l, L + m] - sph_harm_y(l, m, th, ph)).max() for l in range(L + 1) for m in range(-l, l + 1))
    assert err < 1e-12
    assert np.all(Y[3, L + 4 :] == 0) and np.all(Y[3, : L - 3] == 0)  # |m| > l stays zero


def test_project_inverts_synthesize_on_exact_quadrature():
    """Gauss-Legendre x uniform-phi grid integrates degree <= 2L exactly: project(synthesize(c)) == c."""
    L = 12
    rng = np.random.default_rng(1)
    c = np.zeros((L + 1, 2 * L + 1), complex)
    for l in range(L + 1):
        c[l, L] = rng.normal()
        for m in range(1, l + 1):
            z = rng.normal() + 1j * rng.normal()
            c[l, L + m], c[l, L - m] = z, (-1) ** m * np.conj(z)  # real field
    x, wx = np.polynomial.legendre.leggauss(L + 1)
    nphi = 2 * L + 2
    TH, PH = np.meshgrid(np.arccos(x), 2 * np.pi * np.arange(nphi) / nphi, indexing="ij")
    W = np.repeat(wx[:, None], nphi, axis=1) * 2 * np.pi / nphi
    f = Yl.synthesize(c, TH, PH)
    assert np.allclose(Yl.project(f.ravel(), TH.ravel(), PH.ravel(), W.ravel(), L), c, atol=1e-12)
    with pytest.raises(ConfigError, match="real field"):
        Yl.project(f.ravel() + 0j, TH.ravel(), PH.ravel(), W.ravel(), L)


def test_scale_factors_and_low_l_unscaled():
    s = H.scale_factors(4, 0.5)
    assert s[0] == s[1] == 1.0
    assert s[2] == pytest.approx(math.sqrt(4 / 0.5)) and s[4] == pytest.approx(math.sqrt(18 / 0.5))


# --------------------------------------------------------------------------- recovery of injected modes
MODES = [(2, 2, "re"), (2, 0, "re"), (3, 1, "im"), (5, 3, "re"), (6, 0, "re"), (8, 5, "im"), (10, 4, "re"),
         (10, 10, "im")]


@pytest.mark.parametrize("l, m, part", MODES)
def test_injected_mode_recovered_level5(sphere5, l, m, part):
    """r = R (1 + eps Re/Im Y_lm) on a level-5 icosphere. Measured (rule "pn"): amplitude error <= 2e-4 and
    largest leakage into any other mode (l >= 1) <= 2e-5 of the injected amplitude, for l <= 10."""
    v, f, th, ph = sphere5
    eps, L = 0.01, 24
    c = _unscaled(H.decompose(v * (1 + eps * _mode(l, m, part, th, ph))[:, None], f, L, delta=1.0), 1.0)
    exp = _expected(l, m, part, eps, L)
    err = abs(c[l, L + m] - exp[l, L + m]) / abs(exp[l, L + m])
    leak = np.abs(c - exp)
    leak[0] = 0  # l = 0 absorbs the change of the equivalent radius
    leak[l, L + m] = leak[l, L - m] = 0
    assert err < 1e-3  # the brief asks < 2 %
    assert leak.max() / abs(exp[l, L + m]) < 1e-4
    # the negative-m partner obeys the reality condition exactly
    assert c[l, L - m] == pytest.approx((-1) ** m * np.conj(c[l, L + m]))


@pytest.mark.parametrize("rule, tol", [("pn", 1e-3), ("vertex", 1e-3), ("centroid", 2.5e-2)])
def test_rules_all_recover_l10(sphere5, rule, tol):
    """The paper-literal centroid rule underestimates by ~h^2 l(l+1)/12 (1.6 % at l = 10, level 5)."""
    v, f, th, ph = sphere5
    eps, L = 0.01, 12
    c = _unscaled(H.decompose(v * (1 + eps * _mode(10, 4, "re", th, ph))[:, None], f, L, 1.0, rule=rule), 1.0)
    assert abs(c[10, L + 4] / (eps / 2) - 1) < tol


def test_smooth_ellipsoid_has_no_spurious_wrinkles():
    """Only the pn rule keeps the mesh pattern out of high l: on the smooth 1:0.8:1 ellipsoid (level 4) the
    spurious Delta_l for 20 <= l <= 30 stays below 1e-4 and l_* ~ 4 (the ellipsoid's own l = 4 content)."""
    m = M.make_vesicle(level=4, axes=(1, 0.8, 1))
    u = H.decompose(m.vertices, m.faces, 40)
    D = H.delta_l(u)
    assert D[20:31].max() < 1e-4
    assert 3.9 < H.characteristic_l(D) < 4.5
    D_vertex = H.delta_l(H.decompose(m.vertices, m.faces, 40, rule="vertex"))
    assert D_vertex[20:31].max() > 100 * D[20:31].max()


@pytest.fixture(scope="module")
def quasiuniform_ellipsoid():
    """The 1:0.8:1 ellipsoid (Delta = 0.116) on a 1000-vertex quasi-uniform mesh: irregular node weights."""
    v, f = M.quasiuniform_sphere(1000, seed=0, lloyd_steps=8)
    axes = M.axes_for_delta(0.116, v, f)
    X = M.ellipsoid_from_sphere(v, f, axes)
    return X, f, Sf.resolvable_l_max(X, f), axes


def test_least_squares_recovers_a_band_limited_field_on_irregular_nodes(quasiuniform_ellipsoid):
    """A field with degrees <= 12 only, sampled at the pn nodes of the quasi-uniform mesh: the least-squares fit
    returns its coefficients to round-off; the quadrature sum alone does not (its weights integrate products of
    Y_lm only approximately on irregular nodes), and the fit never leaves a larger residual than it."""
    X, f, _, _ = quasiuniform_ellipsoid
    q = H.quadrature(X, f)
    L = 12
    rng = np.random.default_rng(3)
    c = Yl.project(rng.standard_normal(q.theta.size), q.theta, q.phi, q.weights, L)  # any real field's layout
    g = Yl.synthesize(c, q.theta, q.phi)
    c_quad = Yl.project(g, q.theta, q.phi, q.weights, L)
    c_lsq, sweeps = Yl.fit_least_squares(g, q.theta, q.phi, q.weights, L)
    scale = np.abs(c).max()
    assert np.abs(c_lsq - c).max() < 1e-8 * scale
    assert np.abs(c_quad - c).max() > 1e-4 * scale
    assert 1 <= sweeps <= 8

    def resid(cc):
        return float(np.sum(q.weights * (g - Yl.synthesize(cc, q.theta, q.phi)) ** 2))

    assert resid(c_lsq) <= resid(c_quad)


def test_least_squares_removes_the_quadrature_floor_of_a_quasi_uniform_mesh(quasiuniform_ellipsoid):
    """The smooth ellipsoid has no content at high l, but the quadrature on irregular nodes aliases into every l,
    growing towards the resolvable l (measured: Delta_l ~ 2e-3 at l = 25 on 1000 vertices, 1.5e-3 at l = 48 on
    5351). The least-squares fit leaves < 1e-6 there, and gets the ellipsoid's own l = 2-10 content of a
    40962-vertex icosphere (the reference: both fits agree there) where the quadrature misses l = 8 by 18% and
    l = 10 by 6x."""
    X, f, L, axes = quasiuniform_ellipsoid
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", H.ResolutionWarning)
        D_q = H.delta_l(H.decompose(X, f, L, delta=0.116))
        D_ls = H.delta_l(H.decompose(X, f, L, delta=0.116, fit="least_squares"))
    high = slice(14, L + 1)
    assert D_q[high].max() > 1e-4
    assert D_ls[high].max() < 1e-6
    v6, f6 = M.icosphere(6)
    D_ref = H.delta_l(H.decompose(M.ellipsoid_from_sphere(v6, f6, axes), f6, 12, delta=0.116))
    for l in (2, 4, 6, 8):
        assert D_ls[l] == pytest.approx(D_ref[l], rel=0.02)
    assert D_ls[10] == pytest.approx(D_ref[10], rel=0.1)
    assert abs(D_q[8] / D_ref[8] - 1) > 0.1
    with pytest.raises(ConfigError, match="fit"):
        H.decompose(X, f, L, fit="exact")


# --------------------------------------------------------------------------- invariances
def test_delta_l_invariant_under_rotation_about_z(sphere5):
    v, f, th, ph = sphere5
    L, eps, alpha = 16, 0.01, 0.7

    def shape(p):
        return 0.02 * _mode(2, 2, "re", th, p) + eps * _mode(7, 3, "im", th, p) + eps * _mode(12, 5, "re", th, p)

    u0 = H.decompose(v * (1 + shape(ph))[:, None], f, L, 1.0)
    u1 = H.decompose(v * (1 + shape(ph - alpha))[:, None], f, L, 1.0)  # shape rotated by alpha, mesh fixed
    D0, D1 = H.delta_l(u0), H.delta_l(u1)
    for l in (2, 7, 12):
        assert D1[l] == pytest.approx(D0[l], rel=1e-4)  # measured <= 5e-6
    # and each coefficient picks up the phase exp(-i m alpha)
    m = np.arange(-L, L + 1)
    assert np.allclose(u1[7], u0[7] * np.exp(-1j * m * alpha), atol=1e-3 * np.abs(u0[7]).max())


def test_delta_l_invariant_under_any_rotation(sphere5):
    v, f, th, ph = sphere5
    L = 12
    Rm = Rotation.from_euler("zyz", [0.4, 1.1, -0.8]).as_matrix()

    def field(points):
        t = np.arccos(np.clip(points[:, 2], -1, 1))
        p = np.arctan2(points[:, 1], points[:, 0])
        return 0.02 * _mode(2, 1, "re", t, p) + 0.01 * _mode(5, 2, "im", t, p) + 0.01 * _mode(9, 0, "re", t, p)

    D0 = H.delta_l(H.decompose(v * (1 + field(v))[:, None], f, L, 1.0))
    D1 = H.delta_l(H.decompose(v * (1 + field(v @ Rm))[:, None], f, L, 1.0))  # r(x) = 1 + g(R^T x)
    assert np.allclose(D1[2:], D0[2:], rtol=1e-4, atol=1e-9)  # measured <= 3e-6


def test_translation_does_not_change_amplitudes():
    m = M.make_vesicle(level=3, axes=(1, 0.8, 1))
    u0 = H.decompose(m.vertices, m.faces, 12)
    u1 = H.decompose(m.vertices + np.array([0.3, -0.2, 0.1]), m.faces, 12)
    assert np.allclose(u0, u1, atol=1e-12)
    assert np.abs(u0[1]).max() < 1e-12  # volume centroid: no l = 1 content for a centred symmetric shape


# --------------------------------------------------------------------------- excess area
def test_sum_u_squared_is_two_for_quasispherical_ellipsoid():
    """sum_{l>=2} |u_lm|^2 = 2 with Delta the mesh's own excess area (measured 1.9926 at level 5)."""
    m = M.make_vesicle(level=5, axes=(1, 0.8, 1))
    u = H.decompose(m.vertices, m.faces, 32)  # delta defaults to the meshed Delta = 0.116
    assert H.delta_l(u)[2:].sum() == pytest.approx(2.0, abs=0.01)


@pytest.mark.parametrize("l, m, eps", [(2, 2, 0.02), (4, 1, 0.02), (6, 3, 0.02), (10, 4, 0.01)])
def test_excess_area_from_u_matches_mesh(sphere5, l, m, eps):
    """Delta from the u_lm vs the mesh's own Delta, less the faceted sphere's own 7.7e-4 (measured: 0.05 % at
    l = 2 to 0.7 % at l = 10)."""
    v, f, th, ph = sphere5
    base = M.Mesh(v, f).excess_area()
    vv = v * (1 + eps * _mode(l, m, "re", th, ph))[:, None]
    D = M.Mesh(vv, f).excess_area()
    u = H.decompose(vv, f, 32, delta=D)
    assert H.excess_area(u, D) == pytest.approx(D - base, rel=0.02)


# --------------------------------------------------------------------------- quadrature weights
def test_solid_angles_sum_to_four_pi_and_paper_weights_do_not():
    for kw in (dict(axes=(1, 0.8, 1)), dict(target_delta=0.997)):
        m = M.make_vesicle(level=3, **kw)
        q = H.quadrature(m.vertices, m.faces)
        assert q.weights.sum() == pytest.approx(4 * np.pi, rel=1e-12)
        qp = H.quadrature(m.vertices, m.faces, weights="paper", rule="centroid")
        assert qp.weights.sum() > 4 * np.pi * 1.01  # A_i / r_i^2 over-weights tilted facets
    assert qp.weights.sum() / (4 * np.pi) - 1 > 0.1  # Delta = 1: +12 %


def test_pn_centers_lie_on_the_sphere():
    v, f = M.icosphere(3)
    off_flat = np.abs(np.linalg.norm(v[f].mean(1), axis=1) - 1).max()
    off_pn = np.abs(np.linalg.norm(Sf.pn_centers(v, f), axis=1) - 1).max()
    assert off_flat > 1e-3 and off_pn < 1e-2 * off_flat


def test_resolution_warning():
    v, f = M.icosphere(2)
    lres = Sf.resolvable_l_max(v, f)
    assert 8 <= lres <= 12
    with pytest.warns(H.ResolutionWarning, match="exceeds"):
        H.decompose(v, f, lres + 5, 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        H.decompose(v, f, lres, 1.0)


# --------------------------------------------------------------------------- scalar diagnostics
def test_characteristic_l_eq31():
    D = np.zeros(12)
    D[5] = 3.0
    assert H.characteristic_l(D) == pytest.approx(5.0)
    D[2] = 100.0  # l = 2 is excluded from eq. (31)
    assert H.characteristic_l(D) == pytest.approx(5.0)
    D = np.zeros(12)
    D[4], D[8] = 18.0 * 1.0, 70.0 * 2.0  # |c|^2 sums 1 and 2 (Delta_l = (l^2+l-2) |c|^2 / 1)
    assert H.characteristic_l(D) == pytest.approx(math.sqrt((16 + 2 * 64) / 3))
    assert H.characteristic_l(D, l_max=6) == pytest.approx(4.0)
    both = H.characteristic_l(np.stack([D, D]), l_max=np.array([6, 11]))
    assert both == pytest.approx([4.0, math.sqrt(48)])
    assert np.isnan(H.characteristic_l(np.r_[0, 0, 1.0, 0]))


def test_t_star_and_l_max_nontrivial():
    t = np.array([-0.2, -0.1, 0.0, 0.1, 0.2, 0.3])
    d2 = np.array([0.0, 0.1, 1.0, 0.5, 0.2, 0.4])  # smaller values before the reversal are ignored
    assert H.t_star(t, d2) == pytest.approx(0.2) and H.t_star_index(t, d2) == 4
    assert np.isnan(H.t_star(t[:2], d2[:2]))
    u = np.zeros((6, 11), complex)
    u[2, 5] = 1.0
    u[4, 7] = 2e-5
    u[5, 8] = 5e-6
    assert H.l_max_nontrivial(u) == 4
    assert H.l_max_nontrivial(u, threshold=1e-6) == 5
    assert list(H.l_max_nontrivial(np.stack([u, 0 * u]))) == [4, -1]


def test_wrinkle_spectrum_and_mean_square_amplitude(sphere5):
    """A single l = 12 wrinkle on a sphere: the fitted ellipsoid is the sphere, A_p = eps Re Y_12,4, so
    u~_12,4 = eps / 2 and A_p-bar = eps^2 <(Re Y)^2> = eps^2 / (8 pi)."""
    v, f, th, ph = sphere5
    eps, L = 0.01, 20
    vv = v * (1 + eps * _mode(12, 4, "re", th, ph))[:, None]
    r = Sh.analyze_snapshot(vv, f, L, delta=1.0)
    assert np.allclose(r["ellipsoid"][1], 1.0, atol=1e-4)
    ut, Dt = r["u_tilde"], r["Delta_tilde"]
    assert ut[12, L + 4].real == pytest.approx(eps / 2, rel=0.01)
    assert int(np.argmax(Dt)) == 12 and Dt[12] > 1e3 * np.delete(Dt, 12).max()
    assert r["A_p_bar"] == pytest.approx(eps**2 / (8 * np.pi), rel=0.02)
    ut2, Dt2 = Sh.amplitude_spectrum(vv, f, r["ellipsoid"], L)
    assert np.allclose(ut2, ut, atol=1e-12) and np.allclose(Dt2, Dt)
    assert Sh.mean_square_amplitude(r["A_p"], r["areas"]) == pytest.approx(r["A_p_bar"])


def test_field_spectrum_accepts_vertex_or_triangle_values():
    v, f = M.icosphere(4)
    c_tri = H.field_spectrum(v, f, np.ones(len(f)), 4)
    c_ver = H.field_spectrum(v, f, np.ones(len(v)), 4)
    for c in (c_tri, c_ver):
        assert c[0, 4].real == pytest.approx(np.sqrt(4 * np.pi), rel=1e-10)
    with pytest.raises(ConfigError, match="per vertex"):
        H.field_spectrum(v, f, np.ones(7), 4)


def test_resolved_field_keeps_a_smooth_field_and_drops_mesh_noise():
    """A smooth field given per triangle comes back at the vertices (the centroid rule's O(h^2) smoothing only);
    per-triangle white noise, which has no resolvable part to speak of, is cut to a fraction of its rms."""
    from vesicle_core.geometry import mesh as Mm

    m = Mm.make_vesicle("quasiuniform", n_vertices=642, axes=(1.0, 0.8, 1.0))
    v, f = m.vertices, m.faces

    def smooth(p):
        r = p - Sf.volume_centroid(v, f)
        r = r / np.linalg.norm(r, axis=1, keepdims=True)
        return 300.0 + 200.0 * (3 * r[:, 2] ** 2 - 1) + 80.0 * r[:, 0] * r[:, 1] * r[:, 2]  # l = 0, 2, 3

    c = v[f].mean(axis=1)
    got = H.resolved_field(v, f, smooth(c))
    want = smooth(v)
    assert np.sqrt(np.mean((got - want) ** 2)) < 0.01 * np.sqrt(np.mean((want - want.mean()) ** 2))
    noise = np.random.default_rng(1).standard_normal(len(f))
    kept = H.resolved_field(v, f, noise)  # l <= 10 of 1280 independent values: ~(11^2 / 1280)^(1/2) of the rms
    assert np.sqrt(np.mean(kept**2)) < 0.4
