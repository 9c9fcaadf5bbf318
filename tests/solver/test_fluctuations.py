"""Thermal noise (vesicle_core.solver.fluctuations): fluctuation-dissipation against the project's own mobility,
exactly and
by sampling; reproducible counter-based numbers on the NumPy, GPU-layout and stand-in CuPy paths; bad input."""


import numpy as np
import pytest
from scipy import stats

from vesicle_core.errors import ConfigError
from vesicle_core.solver import backend as backend_module
from vesicle_core.solver.backend import get_backend
from vesicle_core.solver.fluctuations import (
    ThermalNoise,
    mobility_divergence,
    mobility_matrix,
    noise_generator,
    rfd_drift,
)
from vesicle_core.solver.ibm import Coupler, Grid
from vesicle_core.solver.kernels import sharpening_symbol
from vesicle_core.solver.mobility import IBMMobility
from vesicle_core.solver.stokes import StokesSolver

N, L = 8, 4.0
KT, DT = 0.0405, 2e-3
# three markers: two at 1.1 h (a membrane's neighbours), one across the box
X3 = np.array([[0.13, -0.21, 0.37], [0.68, -0.05, 0.29], [-1.4, 1.1, -0.9]])


def _setup(coupling="kernel", interleave=None, backend=None, n=N):
    be = backend or get_backend("numpy")
    g = Grid(n, L)
    W = sharpening_symbol(n, "peskin4", 0.01) if coupling == "sharp" else None
    st = StokesSolver(g, be, force_filter=W, interleave=interleave)
    return g, be, st, IBMMobility(Coupler(g, be), st)


@pytest.mark.parametrize("coupling", ["kernel", "sharp"])
@pytest.mark.parametrize("interleave", [True, False])
def test_sqrt_velocity_squares_to_the_steady_operator(coupling, interleave):
    g, _, st, _ = _setup(coupling, interleave)
    f = np.random.default_rng(1).standard_normal(g.field_shape)
    u = st.velocity(f).copy()
    uu = st.sqrt_velocity(st.sqrt_velocity(f, 2.0).copy(), 0.5)
    assert np.abs(uu - u).max() < 1e-13 * np.abs(u).max()
    # symmetric: <a, R b> = <R a, b>; and R kills gradients of the collocated grid only through xi (k = 0: zero)
    b = np.random.default_rng(2).standard_normal(g.field_shape)
    assert np.isclose(np.vdot(f, st.sqrt_velocity(b).copy()), np.vdot(st.sqrt_velocity(f).copy(), b), rtol=1e-12)
    assert abs(st.sqrt_velocity(np.ones(g.field_shape)).max()) < 1e-14


@pytest.mark.parametrize("coupling", ["kernel", "sharp"])
def test_noise_covariance_is_2kTdtM_exactly(coupling):
    """The noise map z -> J dU is linear, B = c J A^{1/2}; its covariance B B^T (rows by A^{1/2} J^T e_i =
    h^3 A^{1/2} S e_i) must be 2 kT dt M with M from unit forces through IBMMobility, to round-off."""
    g, _, st, mob = _setup(coupling)
    M = mobility_matrix(mob, X3)
    noise = ThermalNoise(st, KT, seed=1)
    c = noise.amplitude(DT)
    mob.prepare(X3)
    rows = []
    for j in range(M.shape[0]):
        F = np.zeros((3, 3))
        F.flat[j] = 1.0
        rows.append(st.sqrt_velocity(mob.coupler.spread(F) * g.h**3, c).reshape(-1).copy())
    B = np.array(rows)
    ref = 2 * KT * DT * M
    assert np.abs(B @ B.T - ref).max() < 1e-12 * np.abs(ref).max()
    assert np.linalg.eigvalsh(M).min() > 0  # a proper covariance for the whitening below


def _fdt_sample(noise, mob, X, n_draws, dt=DT):
    """n_draws interpolated noise displacements (n_draws, 3 n), one step counter each."""
    mob.prepare(X)
    return np.array([mob.coupler.interpolate(noise.displacement(dt, s)).reshape(-1).copy()
                     for s in range(n_draws)])


def _fdt_checks(sample, cov):
    """Whiten by the Cholesky factor of the expected covariance; return the statistics the test bounds."""
    Lc = np.linalg.cholesky(cov)
    y = np.linalg.solve(Lc, sample.T).T  # should be iid N(0, 1)
    n, d = y.shape
    C = y.T @ y / n
    dev = np.abs(C - np.eye(d)).max() / np.sqrt(2.0 / n)  # in units of the diagonal's sampling std
    mean = np.abs(y.mean(0)).max() * np.sqrt(n)
    p_normal = stats.kstest(y.ravel(), "norm").pvalue
    p_chi2 = stats.kstest((y**2).sum(1), stats.chi2(d).cdf).pvalue
    return dev, mean, p_normal, p_chi2


def _passes(stat):
    dev, mean, p_normal, p_chi2 = stat
    # 45 covariance entries and 9 means: max |z| < 5 fails with probability < 1e-4; p-values > 1e-3
    return dev < 5.0 and mean < 5.0 and p_normal > 1e-3 and p_chi2 > 1e-3


@pytest.mark.parametrize("coupling", ["kernel", "sharp"])
def test_fluctuation_dissipation_by_sampling(coupling):
    g, _, st, mob = _setup(coupling)
    cov = 2 * KT * DT * mobility_matrix(mob, X3)
    n = 4000
    stat = _fdt_checks(_fdt_sample(ThermalNoise(st, KT, seed=7), mob, X3, n), cov)
    assert _passes(stat), stat


def test_the_sampling_test_fails_a_staggered_symbol_and_a_missing_sqrt_W():
    """The same statistics reject noise built with |g_k|^2 in place of lam_k (a staggered-grid stochastic stress
    copied onto this grid) and, for the sharp coupling, noise without sqrt(W): the test can fail."""
    g, _, st, mob = _setup("kernel")
    cov = 2 * KT * DT * mobility_matrix(mob, X3)
    wrong = StokesSolver(g, get_backend("numpy"))
    wrong._inv_lam = wrong._ginv.copy()  # 1 / |g|^2 (0 at the Nyquist-type modes) instead of 1 / lam
    assert not _passes(_fdt_checks(_fdt_sample(ThermalNoise(wrong, KT, seed=7), mob, X3, 1000), cov))
    g, _, st_sharp, mob_sharp = _setup("sharp")
    cov_sharp = 2 * KT * DT * mobility_matrix(mob_sharp, X3)
    unfiltered = ThermalNoise(StokesSolver(g, get_backend("numpy")), KT, seed=7)
    assert not _passes(_fdt_checks(_fdt_sample(unfiltered, mob_sharp, X3, 1000), cov_sharp))


def test_same_seed_and_step_give_the_same_numbers_whatever_came_before():
    _, _, st, _ = _setup()
    a = ThermalNoise(st, KT, seed=11)
    for s in range(5):
        a.displacement(DT, s)
    u5 = a.displacement(DT, 5).copy()
    b = ThermalNoise(StokesSolver(Grid(N, L), get_backend("numpy")), KT, seed=11)
    np.testing.assert_array_equal(b.displacement(DT, 5), u5)  # a resumed run: bit-identical
    assert not np.array_equal(b.displacement(DT, 6), u5)
    c = ThermalNoise(st, KT, seed=12)
    assert not np.array_equal(c.displacement(DT, 5), u5)
    z1 = noise_generator(3, 9).standard_normal(1000)
    z2 = noise_generator(3, 9).standard_normal(1000)
    np.testing.assert_array_equal(z1, z2)
    assert abs(np.corrcoef(z1, noise_generator(3, 10).standard_normal(1000))[0, 1]) < 0.15
    assert not np.array_equal(noise_generator(3, 9, stream=1).standard_normal(1000), z1)
    # a float-valued integer seed is the same seed
    np.testing.assert_array_equal(noise_generator(3.0, 9).standard_normal(4), z1[:4])


def test_kT_zero_is_deterministic_and_float32_draws_in_float32():
    _, _, st, _ = _setup()
    assert not np.any(ThermalNoise(st, 0.0, seed=1).displacement(DT, 0))
    be32 = get_backend("numpy", dtype="float32")
    st32 = StokesSolver(Grid(N, L), be32)
    u = ThermalNoise(st32, KT, seed=1).displacement(DT, 0)
    assert u.dtype == np.float32 and np.all(np.isfinite(u)) and np.abs(u).max() > 0


def test_gpu_layout_gives_the_cpu_layout_noise():
    _, _, cpu, _ = _setup(interleave=True)
    _, _, gpu, _ = _setup(interleave=False, backend=get_backend("numpy", fft_library="numpy"))
    a = ThermalNoise(cpu, KT, seed=5).displacement(DT, 3).copy()
    b = ThermalNoise(gpu, KT, seed=5).displacement(DT, 3)
    assert np.abs(a - b).max() < 1e-13 * np.abs(a).max()


def test_cupy_stand_in_draws_the_numpy_numbers(fake_cupy):
    _, calls = fake_cupy
    assert backend_module.cupy_available()
    be = backend_module.get_backend("cupy")
    assert be.is_gpu
    _, _, st_gpu, _ = _setup(backend=be)
    assert not st_gpu.interleaved
    _, _, st_cpu, _ = _setup()
    gpu, cpu = ThermalNoise(st_gpu, KT, seed=21), ThermalNoise(st_cpu, KT, seed=21)
    before = calls["asarray"]
    b = be.asnumpy(gpu.displacement(DT, 4))
    assert calls["asarray"] > before  # drawn on the host and copied
    np.testing.assert_array_equal(gpu.white(4), cpu.white(4))  # the same deviates
    a = cpu.displacement(DT, 4)
    assert np.abs(a - b).max() < 1e-13 * np.abs(a).max()


_SEED_RANGE = r"seed must be an integer in \[0, 18446744073709551615\], got "


@pytest.mark.parametrize("bad,match", [(dict(kT=-0.1), r"kT must lie in \[0.0, inf\], got -0.1"),
                                       (dict(kT=float("nan")), r"kT must be a number"),
                                       (dict(seed=1.5), _SEED_RANGE + "1.5"), (dict(seed="3"), _SEED_RANGE),
                                       (dict(seed=True), _SEED_RANGE), (dict(seed=-1), _SEED_RANGE + "-1"),
                                       (dict(seed=2**64), _SEED_RANGE)])
def test_bad_input_names_the_field_and_range(bad, match):
    _, _, st, _ = _setup()
    kw = dict(kT=KT, seed=0) | bad
    with pytest.raises(ConfigError, match=match):
        ThermalNoise(st, **kw)


def test_bad_step_and_dt():
    _, _, st, _ = _setup()
    noise = ThermalNoise(st, KT, seed=0)
    with pytest.raises(ConfigError, match="step"):
        noise.displacement(DT, -1)
    with pytest.raises(ConfigError, match="step"):
        noise.displacement(DT, 0.5)
    with pytest.raises(ConfigError, match="dt"):
        noise.displacement(0.0, 1)


def test_mobility_divergence_of_a_translation_invariant_pair_is_small():
    """div M at a single marker: the self-mobility's gradient along the grid, ~ the kernel's translation-invariance
    error per cell, small against M / h (docs/history/thermal.md quantifies it); exact FD check against a larger
    step."""
    g, _, _, mob = _setup(n=16)
    X = np.array([[0.11, 0.07, -0.05]])
    d1 = mobility_divergence(mob, X, eps=1e-4)
    d2 = mobility_divergence(mob, X, eps=2e-4)
    m0 = mobility_matrix(mob, X)[0, 0]
    assert np.abs(d1 - d2).max() < 1e-3 * m0 / g.h
    assert np.abs(d1).max() < 0.05 * m0 / g.h


@pytest.mark.parametrize("coupling", ["kernel", "sharp"])
def test_a_free_marker_diffuses_with_hasimotos_coefficient(coupling):
    """8 passive markers in a 16^3 box under the noise alone (Euler-Maruyama in the grid frame, no drift term):
    D from the one-step increments and from the MSD at a lag of 20 steps against kT / (6 pi R_h) [1 - 2.837297 x
    + (4 pi / 3) x^3 - 27.4 x^6], x = R_h / L, with R_h of stokeslet.hydrodynamic_radius (docs/history/thermal.md
    has the
    longer runs: within 0.4% +- 0.3%)."""
    from vesicle_core.validation.stokeslet import HASIMOTO, hydrodynamic_radius

    n, kT, dt, steps, lag = 16, 1.0, 1.0, 3000, 20
    g = Grid(n, float(n))  # h = 1
    W = sharpening_symbol(n, "peskin4", 0.01) if coupling == "sharp" else None
    st = StokesSolver(g, get_backend("numpy"), force_filter=W)
    mob = IBMMobility(Coupler(g, get_backend("numpy")), st)
    R_h = hydrodynamic_radius("peskin4", coupling, 0.01, N=32)
    x = R_h / g.L
    D_H = kT / (6 * np.pi * R_h) * (1 - HASIMOTO * x + 4 * np.pi / 3 * x**3 - 27.4 * x**6)
    noise = ThermalNoise(st, kT, seed=2)
    s = np.array([-4.0, 4.0])
    X = np.stack(np.meshgrid(s, s, s, indexing="ij"), -1).reshape(-1, 3) + 0.37
    traj = [X]
    for k in range(steps):
        mob.prepare(X)
        X = X + mob.coupler.interpolate(noise.displacement(dt, k))
        traj.append(X)
    traj = np.array(traj)
    D_inc = (np.diff(traj, axis=0) ** 2).sum(-1).mean() / (6 * dt)
    D_msd = ((traj[lag:] - traj[:-lag]) ** 2).sum(-1).mean() / (6 * lag * dt)
    assert abs(D_inc / D_H - 1) < 0.02, (D_inc, D_H)
    assert abs(D_msd / D_H - 1) < 0.05, (D_msd, D_H)


class _DiagonalMobility:
    """A stand-in with the IBMMobility interface and a known divergence: M(X) = diag(m(X_i)) (x) I_3,
    m(x) = 1 + 0.3 sin(x_1) cos(2 x_2) + 0.1 x_3, so (div M)_i = grad m(X_i)."""

    def __init__(self):
        self.backend = get_backend("numpy")
        self._X = None

    @staticmethod
    def m(X):
        return 1 + 0.3 * np.sin(X[:, 0]) * np.cos(2 * X[:, 1]) + 0.1 * X[:, 2]

    @staticmethod
    def grad(X):
        return np.stack([0.3 * np.cos(X[:, 0]) * np.cos(2 * X[:, 1]),
                         -0.6 * np.sin(X[:, 0]) * np.sin(2 * X[:, 1]), 0.1 + 0 * X[:, 2]], 1)

    def prepare(self, X):
        self._X = np.asarray(X, dtype=float)

    def apply(self, F):
        return self.m(self._X)[:, None] * F


def test_mobility_divergence_and_rfd_on_a_known_mobility():
    mob = _DiagonalMobility()
    X = np.array([[0.3, -0.7, 0.2], [1.1, 0.4, -0.5]])
    np.testing.assert_allclose(mobility_divergence(mob, X, 1e-5), mob.grad(X), atol=1e-8)
    rfd = np.mean([rfd_drift(mob, X, 2.0, seed=3, step=s) for s in range(4000)], axis=0)
    # per sample 2 grad_c m W_c W_k: std ~ 2 kT |grad m| sqrt(2) / sqrt(n)
    assert np.abs(rfd - 2.0 * mob.grad(X)).max() < 0.06, (rfd, 2.0 * mob.grad(X))


def test_rfd_drift_is_the_ibm_divergence_in_the_mean():
    """On the IBM (N = 8, the three markers) the RFD's mean agrees with kT div M by central differences within its
    sampling error (chi^2 of the 9 standardised differences). A consistency check only: one RFD sample scatters by
    ~60% of kT M_self / h against a drift of 1-4% of it, so 3000 samples cannot tell it from zero; the known
    mobility above is where the estimator's correctness is tested with power."""
    _, _, _, mob = _setup()
    ref = KT * mobility_divergence(mob, X3, 1e-4)
    S = np.array([rfd_drift(mob, X3, KT, seed=4, step=s, delta=1e-4) for s in range(3000)])
    z = (S.mean(0) - ref) / (S.std(0, ddof=1) / np.sqrt(len(S)))
    assert stats.chi2(z.size).sf((z**2).sum()) > 1e-3, z
    m0 = KT * mobility_matrix(mob, X3[:1])[0, 0] / (L / N)  # kT M_self / h
    assert np.abs(ref).max() > 0.01 * m0  # the drift being checked is not zero


@pytest.mark.parametrize("coupling", ["kernel", "sharp"])
def test_noise_field_is_divergence_free_with_the_expected_mode_variances(coupling):
    """On the grid itself: zero mean, zero central-difference divergence, and per mode E sum_c |u_hat_c|^2 =
    c^2 N^3 tr(xi_k) W_k / lam_k (tr xi = 2, and 3 at the 7 Nyquist-type modes where g_k = 0): checked on the
    Nyquist-type modes and on the median over all modes, 1500 draws."""
    from vesicle_core.solver.stokes import gradient_symbol_1d, laplacian_symbol_1d

    g, _, st, _ = _setup(coupling)
    noise = ThermalNoise(st, KT, seed=9)
    n, h = g.N, g.h
    u = noise.displacement(DT, 0).copy()
    assert abs(u.mean(axis=(1, 2, 3))).max() < 1e-15 * abs(u).max()
    div = sum((np.roll(u[a], -1, a) - np.roll(u[a], 1, a)) / (2 * h) for a in range(3))
    assert abs(div).max() < 1e-12 * abs(u).max() / h
    lam1, g1 = laplacian_symbol_1d(n, h), gradient_symbol_1d(n, h)
    lam = lam1[:, None, None] + lam1[None, :, None] + lam1[None, None, :]
    g2 = g1[:, None, None] ** 2 + g1[None, :, None] ** 2 + g1[None, None, :] ** 2
    W = np.ones_like(lam)
    if coupling == "sharp":
        from vesicle_core.solver.kernels import window_symbol_1d

        w1 = window_symbol_1d(n, "peskin4")
        W = 1.0 / np.maximum((w1[:, None, None] * w1[None, :, None] * w1[None, None, :]) ** 2, 0.01)
    lam[0, 0, 0] = 1.0
    expect = noise.amplitude(DT) ** 2 * n**3 * np.where(g2 > 0, 2.0, 3.0) * W / lam
    expect[0, 0, 0] = 0.0
    acc = np.zeros_like(lam)
    draws = 1500
    for s in range(draws):
        acc += (np.abs(np.fft.fftn(noise.displacement(DT, s), axes=(1, 2, 3))) ** 2).sum(0)
    ratio = np.where(expect > 0, acc / draws / np.where(expect > 0, expect, 1.0), 1.0)
    assert acc[0, 0, 0] < 1e-20 * acc.max()
    nyq = [(i, j, k) for i in (0, n // 2) for j in (0, n // 2) for k in (0, n // 2) if (i, j, k) != (0, 0, 0)]
    r_nyq = np.array([ratio[m] for m in nyq])
    # a real Gaussian per component at these modes: 3 dof, relative std sqrt(2 / (3 draws)) = 2.1%
    assert np.abs(r_nyq - 1).max() < 0.1, r_nyq
    assert abs(np.median(ratio[expect > 0]) - 1) < 0.03


class _Unconstrained:
    """The ConstrainedMobility interface over the plain IBM mobility (no tension): enough for ThermalVelocity."""

    def __init__(self, mob):
        self.mobility, self.backend, self.dt, self.step = mob, mob.backend, 1.0, 0

    def prepare(self, X):
        self.mobility.prepare(X)

    def apply(self, W):
        return self.mobility.apply(W)


def test_drift_every_k_steps_is_the_rfd_weighted_by_k_on_those_steps_only():
    """noise_drift_every = 3: steps 0, 3 carry 3x the step's own random finite difference, the others none, and the
    noise is the same draw; the drift's mean per step is kept (sum over a period = sum of the k draws' expectation)
    and the constrained solves fall 3-fold."""
    from vesicle_core.solver.fluctuations import ThermalVelocity

    _, be, st, mob = _setup()
    every1 = ThermalVelocity(st, _Unconstrained(mob), KT, seed=5, drift_every=1)
    every3 = ThermalVelocity(st, _Unconstrained(IBMMobility(Coupler(Grid(N, L), be), st)), KT, seed=5, drift_every=3)
    for step in range(6):
        rfd = rfd_drift(mob, X3, KT, 5, step, delta=every1.delta)
        diff = every3(X3, DT, step) - every1(X3, DT, step)  # the noise cancels: same seed and step
        np.testing.assert_allclose(diff, (2.0 if step % 3 == 0 else -1.0) * rfd, rtol=1e-9, atol=1e-12)
    assert every1.stokes_solves == 3 * every3.stokes_solves == 12
    # 0: no drift at all, the noise alone and no constrained solve
    off = ThermalVelocity(st, _Unconstrained(IBMMobility(Coupler(Grid(N, L), be), st)), KT, seed=5, drift_every=0)
    for step in range(3):
        rfd = rfd_drift(mob, X3, KT, 5, step, delta=every1.delta)
        np.testing.assert_allclose(off(X3, DT, step), every1(X3, DT, step) - rfd, rtol=1e-9, atol=1e-12)
    assert off.stokes_solves == 0
    with pytest.raises(ConfigError, match="drift_every"):
        ThermalVelocity(st, _Unconstrained(mob), KT, seed=5, drift_every=-1)


def test_lm_noise_is_the_mean_of_this_and_the_next_steps_euler_draws():
    _, _, st, _ = _setup()
    euler, lm = ThermalNoise(st, KT, seed=11), ThermalNoise(st, KT, seed=11, scheme="lm")
    e = {n: euler.velocity(DT, n).copy() for n in (4, 5, 6, 8, 9)}
    # consecutive steps reuse the kept draw of step n + 1; a gap (a resumed run) draws afresh: the same numbers
    for n in (4, 5, 8):
        np.testing.assert_allclose(lm.velocity(DT, n), 0.5 * (e[n] + e[n + 1]), rtol=1e-12, atol=1e-14)
    assert lm.n_draws == 5  # steps 4, 5, 6, then 8, 9
    with pytest.raises(ConfigError, match="noise_scheme"):
        ThermalNoise(st, KT, scheme="heun")


@pytest.mark.parametrize("scheme, factor", [("euler", 1.0 / (1.0 - 0.3)), ("lm", 1.0)])
def test_a_trapped_marker_samples_kT_over_k_with_lm_and_the_euler_bias_without(scheme, factor):
    """One marker in a harmonic trap, X' = M (-k X) + noise, at a step with a dt = 0.6 (a = k m_self): Euler's
    stationary variance is (kT / k) / (1 - a dt / 2) = 1.43 kT / k, the averaged noise's is kT / k (the linear
    case, where it is exact). 3000 steps, 3 components; the lag-one correlation (1 - a dt = 0.4) is allowed for."""
    _, _, st, mob = _setup()
    X = np.array([[0.05, -0.02, 0.03]])
    m_self = mobility_matrix(mob, X)[0, 0]
    k = 0.6 / (m_self * DT)
    noise = ThermalNoise(st, KT, seed=13, scheme=scheme)
    samples = []
    for n in range(3000):
        mob.prepare(X)
        X = X + DT * (np.asarray(mob.apply(-k * X)) + np.asarray(mob.coupler.interpolate(noise.velocity(DT, n))))
        if n >= 100:
            samples.append(X[0].copy())
    var = np.var(np.array(samples), axis=0).mean() / (KT / k)
    # se of a variance from 2900 x 3 samples, inflated ~1.5x by the lag-one correlation: ~2.5%
    assert var == pytest.approx(factor, rel=0.08), var


def test_noise_on_markers_much_finer_than_the_grid_warns(caplog):
    """The measured failure (docs/history/thermal.md section 7: area creep, then a CG failure at edge 0.48 h) is
    warned of
    before the run; an edge of ~h, where the 642-vertex runs held their area, is silent, and so is a run without
    noise on the same fine mesh."""
    from vesicle_core.geometry import mesh as M
    from vesicle_core.model.run_config import RunConfig
    from vesicle_core.solver.fluctuations import NOISE_EDGE_MIN, noise_mesh_warning
    from vesicle_core.solver.simulate import _check_mesh_spacing

    assert noise_mesh_warning(NOISE_EDGE_MIN) is None and "0.40 h" in noise_mesh_warning(0.4)
    m = M.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))  # mean edge ~0.25 R
    noisy = dict(scheme="inextensible", tension_space="harmonic", kT=0.0405)
    with caplog.at_level("WARNING", logger="vesicle_core.solver.simulate"):
        _check_mesh_spacing(m, RunConfig(N=16, **noisy))  # h = 0.31: edge ~0.8 h
        assert not caplog.records
        _check_mesh_spacing(m, RunConfig(N=8, **noisy))  # h = 0.625: edge ~0.4 h
        assert "kT > 0" in caplog.text and "edge ~h" in caplog.text
        caplog.clear()
        _check_mesh_spacing(m, RunConfig(N=8, scheme="inextensible", tension_space="harmonic"))
        assert not caplog.records
