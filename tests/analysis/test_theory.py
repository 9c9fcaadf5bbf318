"""Perturbation analysis of Sec. III (theory.py): normalisation, conservation, relaxation, stage 1, l_* vs the paper."""

import math

import numpy as np
import pytest

from vesicle_core.analysis import harmonics as H
from vesicle_core.analysis import theory as T
from vesicle_core.errors import ConfigError
from vesicle_core.model import modes as Mo
from vesicle_core.model.units import chi_from_S

# The four published PA values (Fig. 3 caption, Fig. 5 caption): (Delta, S) -> l_*
PAPER = {(0.116, 553): 14, (0.116, 2224): 25, (0.997, 237): 10, (0.997, 947): 17}
# What eq. (31) gives when evaluated literally in the sum |u|^2 = 2 normalisation (module docstring).
EQ31_AREA = {(0.116, 553): 12.398, (0.116, 2224): 22.612, (0.997, 237): 8.525, (0.997, 947): 15.688}


@pytest.fixture(scope="module")
def paper_runs():
    return {key: T.run_theory(*key, n_out=2001) for key in PAPER}


# --------------------------------------------------------------------------- model pieces


def test_coefficients():
    assert Mo.gamma_l(2) == pytest.approx(144 / 55)
    assert Mo.a_l(2) == pytest.approx(24 / 55)
    assert Mo.gamma_l(1) == 0 and Mo.a_l(1) == 0
    l = 400.0
    assert Mo.gamma_l(l) / (l**3 / 4) == pytest.approx(1, rel=0.01)
    assert Mo.a_l(l) / (l / 4) == pytest.approx(1, rel=0.01)
    # (A_l sigma + Gamma_l) = A_l (sigma + l(l+1))
    ls = np.arange(2, 30)
    assert np.allclose(Mo.gamma_l(ls), Mo.a_l(ls) * ls * (ls + 1))


def test_excess_area_normalisation_is_sum_u2_equal_2():
    """r = R[1 + sum sqrt(Delta/((l-1)(l+2))) u_lm Y_lm] with sum|u|^2 = 2 has excess area Delta (to leading
    order): measured by quadrature of the actual surface with the volume-equivalent radius."""
    from scipy.special import sph_harm_y

    delta = 1e-3
    nth, nph = 200, 400
    x, wx = np.polynomial.legendre.leggauss(nth)
    th = np.arccos(x)[:, None]
    ph = (np.arange(nph) * 2 * np.pi / nph)[None, :]
    rng = np.random.default_rng(3)
    u = {(2, 2): 1.0 + 0j, (2, -2): 1.0 + 0j}
    for l in (3, 5):  # a few more modes; rescale so that sum |u|^2 = 2
        for m in range(0, l + 1):
            z = complex(rng.standard_normal(), 0 if m == 0 else rng.standard_normal()) * 0.3
            u[(l, m)] = z
            if m:
                u[(l, -m)] = (-1) ** m * np.conj(z)
    tot = sum(abs(v) ** 2 for v in u.values())
    u = {k: v * math.sqrt(2 / tot) for k, v in u.items()}

    def radius(theta, phi):
        rho = np.zeros(np.broadcast(theta, phi).shape)
        for (l, m), v in u.items():
            rho = rho + np.real(math.sqrt(delta / ((l - 1) * (l + 2))) * v * sph_harm_y(l, m, theta, phi))
        return 1 + rho

    r = radius(th, ph)
    h = 1e-5
    r_t = (radius(th + h, ph) - radius(th - h, ph)) / (2 * h)
    r_p = (radius(th, ph + h) - radius(th, ph - h)) / (2 * h)
    st = np.sin(th)
    dA = r * np.sqrt(r**2 * st**2 + r_t**2 * st**2 + r_p**2)  # |X_theta x X_phi|
    w = wx[:, None] / st * (2 * np.pi / nph)  # d(theta) d(phi) weights from Gauss-Legendre in cos(theta)
    area = float(np.sum(dA * w))
    vol = float(np.sum(r**3 / 3 * st * w))
    R = (3 * vol / (4 * np.pi)) ** (1 / 3)
    measured = area / R**2 - 4 * np.pi
    assert measured == pytest.approx(delta, rel=0.02)  # with sum|u|^2 = 1 it would be delta/2


def test_initial_state_layout_symmetry_and_normalisation():
    L = 20
    u = Mo.initial_state(L, 553, seed=4)
    assert u.shape == (L + 1, 2 * L + 1)
    l = np.arange(L + 1)[:, None]
    m = np.arange(-L, L + 1)[None, :]
    assert np.all(u[np.abs(m) > l + np.zeros_like(m)] == 0)
    assert np.all(u[:2] == 0)
    # real shape: u_{l,-m} = (-1)^m conj(u_lm)
    assert np.allclose(u[:, ::-1], ((-1.0) ** m) * np.conj(u))
    assert np.sum(np.abs(u) ** 2) == pytest.approx(2.0, abs=1e-14)
    assert u[2, L + 2] == u[2, L - 2] and u[2, L + 2].imag == 0 and u[2, L + 2].real == pytest.approx(1, abs=1e-3)
    # thermal moduli (fixed amplitudes) and default k_B T / kappa of Table III
    var = Mo.thermal_variance(np.arange(L + 1), 553)
    assert var[10] == pytest.approx(2 * 1.380649e-23 * 293 / 1e-19 / (10**4 + 553 * 100 / (24 / 55)))
    for ll in (3, 7, 20):
        assert np.allclose(np.abs(u[ll, L - ll:L + ll + 1]) ** 2, var[ll])
    # reproducible, seed dependent, and independent of the truncation for l <= 20
    assert np.array_equal(u, Mo.initial_state(L, 553, seed=4))
    assert not np.allclose(u[5:], Mo.initial_state(L, 553, seed=5)[5:])
    big = Mo.initial_state(40, 553, seed=4)
    assert np.allclose(big[3:L + 1, 40 - L:40 + L + 1], u[3:])


def test_gaussian_amplitudes_have_the_thermal_mean():
    L = 60
    u = Mo.initial_state(L, 553, seed=1, amplitudes="gaussian")
    var = Mo.thermal_variance(np.arange(L + 1), 553)
    ratio = H.delta_l(u)[20:] / ((2 * np.arange(20, L + 1) + 1) * var[20:])
    assert np.mean(ratio) == pytest.approx(1, abs=0.05)
    assert np.std(ratio) > 0.05  # chi-square scatter, not fixed moduli


def test_forward_stationary_state_and_tension():
    """Without thermal noise u_{2,+-2} = +1 is stationary in the forward flow with sigma = (S - Gamma_2)/A_2."""
    S, L = 553.0, 10
    u = Mo.initial_state(L, S, kT_over_kappa=0.0)
    sigma = T.global_tension(u, +S)
    assert sigma == pytest.approx((S - Mo.gamma_l(2)) / Mo.a_l(2), rel=1e-12)
    assert np.max(np.abs(T.mode_rhs(u, +S))) < 1e-10 * S
    # eq. (12) is exactly d/ds sum |u|^2 = 0, for any state
    v = Mo.initial_state(L, S, seed=2, amplitudes="gaussian", kT_over_kappa=5.0)
    du = T.mode_rhs(v, -S)
    assert abs(np.sum(np.real(np.conj(v) * du))) < 1e-9 * S


def test_thermal_physical_is_cutoff_dominated():
    """The documented reason for the literal thermal spectrum: with the (l-1)(l+2)/Delta factor the initial
    tension depends on the truncation, and at small S the thermal modes exceed the whole excess area."""
    s40 = T.solve(0.116, 553, l_max=40, thermal="physical").sigma(0.0)
    s80 = T.solve(0.116, 553, l_max=80, thermal="physical").sigma(0.0)
    assert s80 < 2.5 * s40 < 0
    lit = [T.solve(0.116, 553, l_max=L).sigma(0.0) for L in (40, 80)]
    assert lit[1] == pytest.approx(lit[0], rel=2e-3)
    assert lit[0] == pytest.approx(-(553 + Mo.gamma_l(2)) / Mo.a_l(2), rel=2e-3)
    with pytest.raises(ConfigError, match="whole excess area"):
        Mo.initial_state(80, 100, delta=0.116, thermal="physical")


# --------------------------------------------------------------------------- characteristic l


def test_characteristic_l_eq31_and_peak():
    D = np.zeros(12)
    D[7] = 0.3
    assert H.characteristic_l(D) == pytest.approx(7)
    assert H.characteristic_l(D, method="peak") == 7
    D[4] = 0.2
    g = lambda l: (l - 1) * (l + 2)  # noqa: E731
    expect = math.sqrt((16 / g(4) * 0.2 + 49 / g(7) * 0.3) / (0.2 / g(4) + 0.3 / g(7)))
    assert H.characteristic_l(D) == pytest.approx(expect)
    assert H.characteristic_l(D, l_max=5) == pytest.approx(4)  # l range 3..l_max
    D2 = D.copy()
    D2[2] = 5.0  # l = 2 is not part of eq. (31)
    assert H.characteristic_l(D2) == pytest.approx(expect)
    assert math.isnan(H.characteristic_l(np.zeros(12)))
    assert math.isnan(H.characteristic_l(np.zeros(12), method="peak"))
    # vectorised over leading axes, per-row l_max, NaN entries ignored
    stack = np.stack([D, D, np.where(np.arange(12) > 8, np.nan, D)])
    out = H.characteristic_l(stack, l_max=np.array([11, 5, 11]))
    assert out == pytest.approx([expect, 4, expect])
    assert T.l_star is H.characteristic_l
    with pytest.raises(ConfigError):
        H.characteristic_l(D, method="mean")


# --------------------------------------------------------------------------- dynamics


@pytest.mark.filterwarnings("ignore:modes up to the truncation")
def test_reduced_integration_matches_brute_force_eq11():
    """The integrating-factor solution agrees with a direct DOP853 integration of eq. (11) for every mode."""
    from scipy.integrate import solve_ivp

    delta, S, L = 0.116, 300.0, 16
    sol = T.solve(delta, S, l_max=L, seed=3, amplitudes="gaussian")
    u0 = sol.u0
    shape = u0.shape

    def rhs(s, y):
        u = (y[: y.size // 2] + 1j * y[y.size // 2:]).reshape(shape)
        du = T.mode_rhs(u, -S).ravel()
        return np.concatenate([du.real, du.imag])

    s_out = np.linspace(0, sol.s_end, 41)
    y0 = np.concatenate([u0.real.ravel(), u0.imag.ravel()])
    ref = solve_ivp(rhs, (0, sol.s_end), y0, method="DOP853", rtol=1e-11, atol=1e-14, t_eval=s_out)
    assert ref.success
    uref = (ref.y[: y0.size // 2] + 1j * ref.y[y0.size // 2:]).T.reshape((-1,) + shape)
    ured = sol.u(s_out)
    assert np.max(np.abs(ured - uref)) < 1e-7
    assert np.allclose(sol.sigma(s_out), T.global_tension(uref, -S), rtol=1e-6, atol=1e-6 * S)


@pytest.mark.parametrize("key", list(PAPER))
def test_conservation_relaxation_and_stage1(paper_runs, key):
    delta, S = key
    ds = paper_runs[key]
    # sum |u_lm|^2 conserved (no renormalisation anywhere), also recomputed from the stored modes
    assert np.max(np.abs(ds["sum_u2"].values - 2)) < 1e-8
    u2 = ds["u_real"] ** 2 + ds["u_imag"] ** 2
    assert np.max(np.abs(u2.sum(("l", "m")).values - 2)) < 1e-8
    # relaxation to the new stationary state u_{2,+-2} = -1 after the reversal
    end = ds.isel(time=-1)
    assert float(end["u_real"].sel(l=2, m=2)) == pytest.approx(-1, abs=1e-8)
    assert float(end["u_real"].sel(l=2, m=-2)) == pytest.approx(-1, abs=1e-8)
    assert float(end["Delta_l"].sel(l=slice(3, None)).sum()) < 1e-10
    assert float(end["sigma"]) == pytest.approx((S - Mo.gamma_l(2)) / Mo.a_l(2), rel=1e-6)
    # stage 1: negative, nearly constant tension at -(S + Gamma_2)/A_2. "Nearly" quantified: the relative change
    # of sigma is ~10x the fraction of the area that has left l = 2. Measured (n_out = 2001), for
    # (0.116, 553), (0.116, 2224), (0.997, 237), (0.997, 947):
    #   while Delta_2 >= 0.999 Delta_2(0): 0.54 %, 1.18 %, 0.41 %, 0.76 %
    #   while Delta_2 >= 0.99  Delta_2(0): 5.7 %, 11.3 %, 3.6 %, 7.3 %
    st = T.stage1_summary(ds, fraction=0.99)
    assert st["all_negative"] and st["n_samples"] >= 20
    assert st["sigma0"] == pytest.approx(-(S + Mo.gamma_l(2)) / Mo.a_l(2), rel=2e-3)
    assert st["max_rel_change"] < 0.12
    assert T.stage1_summary(ds, fraction=0.999)["max_rel_change"] < 0.015
    # Delta_2 has its minimum at t_* and is (almost) emptied there
    D2 = ds["Delta_l"].sel(l=2)
    dt = float(ds["time"][1] - ds["time"][0])
    assert abs(float(ds["time"][int(np.argmin(D2.values))]) - float(ds["t_star"])) <= dt
    assert float(ds["Delta_2_min"]) < 2e-3


@pytest.mark.parametrize("key", list(PAPER))
def test_published_l_star(paper_runs, key):
    """The paper's four PA values (14, 25, 10, 17).

    * l_peak (argmax_l Delta_l(t_*), the definition printed at the start of Sec. V.A) reproduces all four
      exactly in the sum|u|^2 = 2 normalisation implied by eq. (10).
    * eq. (31) taken literally in that normalisation gives 12.40, 22.61, 8.53, 15.69: 1.3-2.4 below the paper
      (rounded 12, 23, 9, 16: S = 553 and 2224 miss the +-1 band). This is the honest result, asserted as such.
    * eq. (31) in the sum|u|^2 = 1 normalisation (equivalent to S -> sqrt(2) S) gives 13.70, 25.00, 9.41, 17.34,
      within +-1 of all four -- the ~10 % normalisation effect the issue mentions.
    """
    ds = paper_runs[key]
    assert float(ds["l_peak"]) == PAPER[key]
    assert abs(float(ds["l_peak"]) - PAPER[key]) <= 1
    assert float(ds["l_star"]) == pytest.approx(EQ31_AREA[key], abs=0.01)
    unit = T.solve(*key, normalisation="unit")
    assert abs(unit.l_star - PAPER[key]) <= 1
    assert 1.08 < unit.l_star / float(ds["l_star"]) < 1.16
    # l range of eq. (31): 3..l_max_nontrivial, the largest l with some |u_lm(t_*)| > 1e-5
    lmax = int(ds["l_max_nontrivial"])
    assert 3 < lmax < int(ds.attrs["l_max"])
    assert H.characteristic_l(ds["Delta_l_star"].values, lmax) == pytest.approx(float(ds["l_star"]))


@pytest.mark.parametrize("key", [(0.116, 553), (0.997, 947)])
def test_l_star_robust_to_seed_and_truncation(key):
    fixed = [T.solve(*key, seed=s).l_star for s in (0, 1, 2)]
    assert max(fixed) - min(fixed) < 1e-9  # phases never enter Delta_l
    gauss = np.array([T.solve(*key, seed=s, amplitudes="gaussian").l_star for s in range(6)])
    # Gaussian (thermal-equilibrium) moduli: measured sd 0.10-0.20 over 10 seeds
    assert np.std(gauss, ddof=1) < 0.35
    assert np.all(np.abs(gauss - fixed[0]) < 0.7)
    a = T.solve(*key, l_max=40).l_star
    b = T.solve(*key, l_max=90).l_star
    assert a == pytest.approx(b, rel=1e-5)


def test_dataset_layout(paper_runs):
    ds = paper_runs[(0.116, 553)]
    L = int(ds.attrs["l_max"])
    assert list(ds["l"].values) == list(range(L + 1))
    assert list(ds["m"].values) == list(range(-L, L + 1))
    assert ds["u_real"].dims == ("time", "l", "m") and ds["Delta_l"].dims == ("time", "l")
    assert ds["sigma"].dims == ("time",)
    assert np.isnan(ds["u_real"].sel(l=3, m=4)).all() and np.isnan(ds["u_imag"].sel(l=0, m=1)).all()
    assert not np.isnan(ds["u_real"].sel(l=3, m=-3)).any()
    for name in ("t_star", "l_star", "l_max_nontrivial"):
        assert ds[name].ndim == 0
    for name in list(ds.data_vars) + list(ds.coords):
        assert "units" in ds[name].attrs and "long_name" in ds[name].attrs, name
    for key in ("delta", "S", "chi", "seed", "kT_over_kappa", "normalisation"):
        assert key in ds.attrs
    chi = chi_from_S(553, 0.116)
    assert ds.attrs["chi"] == pytest.approx(chi) and chi == pytest.approx(66.7, abs=0.1)  # paper: chi = 67
    assert np.allclose(ds["time"].values, chi * ds["t_tau"].values)
    assert ds.attrs["kT_over_kappa"] == pytest.approx(1.380649e-23 * 293 / 1e-19)
    # Delta_l is sum_m |u_lm|^2 of the stored modes
    D = (ds["u_real"] ** 2 + ds["u_imag"] ** 2).sum("m")
    assert np.allclose(D.values, ds["Delta_l"].values, rtol=1e-10, atol=1e-300)


def test_errors():
    with pytest.raises(ConfigError):
        T.run_theory(-0.1, 553)
    with pytest.raises(ConfigError):
        T.run_theory(0.116, 0.0)
    with pytest.raises(ConfigError, match="normalisation"):
        T.solve(0.116, 553, normalisation="sphere")
    with pytest.raises(ConfigError, match="t_end"):
        T.solve(0.116, 553, t_end=0.05)
    with pytest.raises(ConfigError, match="at least 3"):
        T.sweep(0.116, [100, 200])


def test_sweep_exponent():
    """Fig. 4: 15 S log-spaced in [100, 9500] at Delta = 0.116. Checked against math and the model's structure,
    not against a stored value: the fitted exponent is the log-log least-squares slope; l_* rises with S; it
    cannot rise faster than the largest unstable mode, l(l+1) < |sigma_0| ~ S, i.e. b < 1/2; and no mode reaches
    the truncation. (docs/validation.md compares b with the paper's 0.372; cutoff.py shows what a truncation
    does to it.)"""
    S = np.logspace(2, math.log10(9500), 15)
    ds = T.sweep(0.116, S)
    assert ds.sizes["S"] == 15
    b, lo, hi = (float(ds[f"l_star_exponent{s}"]) for s in ("", "_ci_low", "_ci_high"))
    slope = np.polyfit(np.log(S), np.log(ds["l_star"].values), 1)[0]
    assert b == pytest.approx(slope, rel=1e-10)
    assert lo < b < hi
    assert 0.25 < b < 0.5 and 0.25 < float(ds["l_peak_exponent"]) < 0.5
    assert np.all(np.diff(ds["l_star"].values) > 0)
    assert np.all(ds["l_max_nontrivial"].values < ds["l_max"].values)
    assert float(ds["l_star_r2"]) > 0.99


@pytest.mark.slow
def test_sweep_exponent_gaussian_seeds():
    """With thermal-equilibrium (Gaussian) moduli the exponent is the same within its scatter."""
    S = np.logspace(2, math.log10(9500), 15)
    bs = [float(T.sweep(0.116, S, seed=s, amplitudes="gaussian")["l_star_exponent"]) for s in range(3)]
    assert np.all(np.abs(np.array(bs) - 0.430) < 0.02)


# --------------------------------------------------------------------------- the PA as a grid carries it
def test_grid_damped_modes_follow_the_damped_mode_equation():
    """du_lm/ds = -r_l (Gamma_l + A_l sigma) u_lm for l >= 3, with sigma of eq. (12) from the damped rates, and
    the area sum |u|^2 still conserved (finite differences of the dense solution)."""
    from vesicle_core.analysis.theory import grid_damping, solve
    from vesicle_core.model.modes import a_l, gamma_l

    h = 5.0 / 128
    sol = solve(0.116, 553.0, grid_h=h, t_end=0.5)
    s, ds = 0.3 * sol.s_end, 1e-7 * sol.s_end
    u = sol.u([s - ds, s, s + ds])
    dudt = (u[2] - u[0]) / (2 * ds)
    l = np.arange(sol.l_max + 1)
    r = grid_damping(l, h)
    sig = float(sol.sigma(s))
    pred = -(r * (gamma_l(l) + a_l(l) * sig))[:, None] * u[1]
    big = np.abs(u[1]) > 1e-8
    big[:3] = False
    np.testing.assert_allclose(dudt[big], pred[big], rtol=1e-5)
    D = sol.delta_l(np.linspace(0, sol.s_end, 50)).sum(axis=-1)
    assert np.ptp(D) < 1e-8 * D.mean()
    assert r[2] > 0.99 and r[25] < 0.5  # l = 2 barely damped, the wrinkles strongly at N = 128


def test_grid_damping_lowers_lstar_towards_the_continuum_with_refinement():
    from vesicle_core.analysis.theory import solve

    ls = [solve(0.116, 2224.0, grid_h=h).l_star for h in (5.0 / 128, 5.0 / 256, 1e-6)]
    assert ls[0] < ls[1] < ls[2]
    assert abs(ls[2] / solve(0.116, 2224.0).l_star - 1) < 1e-6


def test_grid_pa_of_the_sharp_coupling_sits_closer_to_the_continuum():
    """The sharp coupling's damping (kernels.SHARP_RESOLUTION) keeps the wrinkle band nearly undamped: at N = 128 its
    grid PA is within 5% of the continuum l_* (measured 21.85 against 22.61), the kernel's 36% below (14.4)."""
    from vesicle_core.analysis.theory import solve

    cont = solve(0.116, 2224.0).l_star
    sharp = solve(0.116, 2224.0, grid_h=5.0 / 128, coupling="sharp").l_star
    kern = solve(0.116, 2224.0, grid_h=5.0 / 128).l_star
    assert kern < 0.7 * cont
    assert 0.95 * cont < sharp <= cont * (1 + 1e-9)


def test_theory_cli_grid_h_writes_the_damped_pa(tmp_path):
    import xarray as xr

    from vesicle_core.analysis.theory import solve
    from vesicle_core.cli import main

    out = tmp_path / "t.nc"
    assert main(["theory", "--delta", "0.116", "--S", "553", "--grid-h", "0.0390625", "--no-modes", "-o",
                 str(out)]) == 0
    with xr.open_dataset(out) as ds:
        assert ds.attrs["grid_h"] == 0.0390625 and ds.attrs["kernel"] == "peskin4"
        assert ds.attrs["coupling"] == "kernel"
        assert abs(float(ds.l_star) - solve(0.116, 553.0, grid_h=0.0390625).l_star) < 1e-9


def test_truncation_warning_only_where_the_truncation_matters():
    """Continuum PA cut at a small l_max: the wrinkles reach the cut and l_* moves, so it warns. The PA on a
    grid: the modes the grid cannot move keep their (tiny) seed amplitude up to any l_max, l_* does not move
    with l_max, and it stays silent."""
    import warnings

    from vesicle_core.analysis.theory import solve

    with pytest.warns(UserWarning, match="truncation"):
        cut = solve(0.116, 2224.0, l_max=16)
    assert abs(cut.l_star / solve(0.116, 2224.0).l_star - 1) > 0.05
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = solve(0.116, 2224.0, grid_h=5.0 / 128, l_max=62)
    b = solve(0.116, 2224.0, grid_h=5.0 / 128, l_max=100)
    assert a.l_max_nontrivial == 62 and abs(a.l_star / b.l_star - 1) < 1e-4
