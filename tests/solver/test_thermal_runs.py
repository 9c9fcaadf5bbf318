"""Thermal noise in an inextensible run (run parameters kT, noise_seed; fluctuations.ThermalVelocity): the
constraint projects the noise, and the projected noise has the constrained mobility's covariance 2 kT N / dt
(checked by sampling, with a counter-test that the raw noise fails); bad input; a short noisy run."""

import numpy as np
import pytest
import xarray as xr
from scipy import stats
from unit_run import unit_run

from vesicle_core.errors import ConfigError
from vesicle_core.geometry import mesh as Mm
from vesicle_core.solver.integrators import Inextensible
from vesicle_core.solver.mobility import IBMSolver
from vesicle_core.solver.simulate import run
from vesicle_core.solver.tension import face_D

KT, DT = 0.0405, 1e-3


def _thermal_setup(space):
    """A 42-vertex vesicle on a 16^3 grid with the harmonic tension (l_t = 3) or the per-triangle one and a stiff
    compliance (Lambda 1e12), so that the constraint is rigid to 1e-6 and the projection exact to far below
    sampling accuracy. noise_scheme euler: the samples below are one step's draws, independent across steps (lm's
    velocity is the mean of two consecutive such draws, tests/solver/test_fluctuations.py)."""
    m = Mm.make_vesicle("icosphere", level=1, axes=(1.0, 0.9, 1.0))
    extra = {"tension_l_max": 3} if space == "harmonic" else {}
    cfg = unit_run(chi=0.0, stretch=0.0, N=16, scheme="inextensible", tension_space=space, Lambda=1e12,
                    cg_tol=1e-12, cg_maxiter=2000, kT=KT, noise_seed=11, noise_scheme="euler",
                    **extra)
    s = IBMSolver(m.faces, m.vertices, cfg)
    integ = Inextensible(s, 1e-3, X0=m.vertices)
    X = s.xp.asarray(m.vertices)
    _, geo = s.forces(X)
    return s, integ, X, geo


@pytest.fixture(scope="module")
def thermal():
    return _thermal_setup("harmonic")


@pytest.fixture(scope="module", params=["harmonic", "triangle"])
def either_space(request):
    return _thermal_setup(request.param)


def _projected(integ, geo, u):
    """The velocity the tension solve makes of a known velocity u with no forces and no area error."""
    c = integ.thermal.constrained
    c.dt, c.step = DT, 0
    zero = np.zeros(geo.area.shape[0])
    if integ.space is None:
        return integ.tension.solve(geo, 0.0 * u, u, zero, DT, zero)[1]
    return integ.tension.solve(geo, 0.0 * u, u, zero, DT, np.zeros(integ.space.K), seed=0)[2]


def _area_rates(integ, U, geo, topo):
    """What the tension space constrains: B^T D U (harmonic) or D U per triangle."""
    d = face_D(U, geo, topo)
    return d if integ.space is None else integ.space.B.T @ d


def _constrained_matrix(integ, X):
    c = integ.thermal.constrained
    c.dt, c.step = DT, 0
    c.prepare(X)
    n = X.shape[0]
    cols = []
    for j in range(3 * n):
        W = np.zeros(3 * n)
        W[j] = 1.0
        cols.append(np.asarray(c.apply(W.reshape(n, 3))).reshape(-1))
    return np.array(cols).T


def _noise_sample(integ, X, n_draws, project):
    th, geo = integ.thermal, integ.thermal.constrained.geometry(X)
    out = []
    for k in range(n_draws):
        integ.mobility.prepare(X)
        u = integ.mobility.coupler.interpolate(th.noise.velocity(DT, k))
        out.append(np.asarray(_projected(integ, geo, u) if project else u).reshape(-1))
    return np.array(out)


def _whitened_stats(sample, N):
    """Whiten by 2 kT N / dt in its range; (max covariance deviation in sampling sigmas, max |mean| in sigmas,
    KS p-value of normality, the share of the sample's power outside the range of N)."""
    lam, V = np.linalg.eigh(0.5 * (N + N.T))
    keep = lam > 1e-6 * lam.max()
    Vr = V[:, keep]
    y = sample @ Vr / np.sqrt(2 * KT * lam[keep] / DT)
    n = y.shape[0]
    C = y.T @ y / n
    dev = np.abs(C - np.eye(C.shape[0])).max() / np.sqrt(2.0 / n)
    mean = np.abs(y.mean(0)).max() * np.sqrt(n)
    p = stats.kstest(y.ravel(), "norm").pvalue
    null = ((sample @ V[:, ~keep]) ** 2).sum() / (sample**2).sum()
    return dev, mean, p, null


def _passes(st):
    dev, mean, p, null = st
    return dev < 5.5 and mean < 5.0 and p > 1e-3 and null < 1e-6


def test_the_constraint_removes_the_area_changing_part_of_the_noise(either_space):
    s, integ, X, geo = either_space
    integ.mobility.prepare(X)
    u = integ.mobility.coupler.interpolate(integ.thermal.noise.velocity(DT, 3))
    U = _projected(integ, geo, u)
    before = np.linalg.norm(_area_rates(integ, u, geo, s.membrane.topo))
    after = np.linalg.norm(_area_rates(integ, U, geo, s.membrane.topo))
    assert before > 0 and after < 1e-6 * before


@pytest.mark.slow  # ~40 s per tension space: 1,500 tension solves at a tolerance of 1e-12
def test_projected_noise_has_the_constrained_mobility_covariance(either_space):
    """Fluctuation-dissipation under the constraint, in both tension spaces: P u has covariance 2 kT N / dt, N the
    constrained mobility measured column by column through the same tension solve. The raw noise (covariance
    2 kT M / dt) fails the same statistics: it has power where N has none."""
    s, integ, X, geo = either_space
    N = _constrained_matrix(integ, X)
    assert np.abs(N - N.T).max() < 1e-6 * np.abs(N).max()  # the constrained mobility is symmetric
    st = _whitened_stats(_noise_sample(integ, X, 1500, project=True), N)
    assert _passes(st), st
    raw = _whitened_stats(_noise_sample(integ, X, 300, project=False), N)
    assert not _passes(raw), raw


@pytest.mark.parametrize(("kw", "match"), [
    ({"kT": -0.1}, r"kT must lie in \[0.0, 1000.0\]"),
    ({"noise_seed": 1.5}, "noise_seed must be an integer"),
    ({"noise_seed": -1}, r"noise_seed must lie in \[0, 2147483647\]"),
    ({"kT": 0.04, "scheme": "projection"}, "kT > 0 needs scheme 'inextensible'"),
    ({"kT": 0.04, "scheme": "inextensible", "seed_spectrum": "thermal", "stationary_tol": 0.0},
     "kT = 0.04 with seed_spectrum 'thermal'.*second thermal spectrum.*seed_spectrum: mesh"),
])
def test_bad_thermal_input_names_the_field(kw, match):
    with pytest.raises(ConfigError, match=match):
        unit_run(**kw)


def test_a_noisy_run_completes_holds_area_and_volume_and_differs_by_seed(tmp_path):
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    base = {"chi": 50.0, "N": 16, "scheme": "inextensible", "tension_space": "harmonic", "stretch": 0.1,
            "t_end": 0.1, "output_every": 0.05, "kT": KT}
    out = {}
    for seed in (1, 2):
        out[seed] = xr.open_dataset(run(m, unit_run(**base, noise_seed=seed), tmp_path / str(seed),
                                        progress=False)).load()
    cold = xr.open_dataset(run(m, unit_run(**{**base, "kT": 0.0}), tmp_path / "cold", progress=False)).load()
    for ds in out.values():
        assert ds.attrs["kT"] == KT
        assert np.abs(ds.area_drift.values).max() < 5e-3 and np.abs(ds.volume_drift.values).max() < 5e-3
    # the two seeds and the deterministic run end apart by more than round-off, by less than the mesh spacing
    d12 = np.abs(out[1].node_x.values[-1] - out[2].node_x.values[-1]).max()
    d1c = np.abs(out[1].node_x.values[-1] - cold.node_x.values[-1]).max()
    assert 1e-6 < d12 < 0.1 and 1e-6 < d1c < 0.1


def test_a_noisy_run_that_drifts_beyond_max_drift_stops_as_unstable(tmp_path):
    """The noise's area and volume change is watched like any other: past max_drift the run stops with
    NumericalInstability (the CLI's exit 3), writes failure.nc and leaves no complete-looking trajectory.
    max_drift = 5e-5 lies between this case's deterministic drift (6e-6 in area) and its noisy one at 10 kT
    (2-3e-4), so it is the noise that trips it: the same run at kT = 0 completes."""
    import dataclasses

    from vesicle_core.errors import NumericalInstability
    from vesicle_core.solver.trajectory import FAILURE, TRAJECTORY

    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    cfg = unit_run(chi=0.0, N=16, scheme="inextensible", tension_space="harmonic", stretch=0.0, t_end=0.05,
                    output_every=0.005, kT=10 * KT, noise_seed=3, max_drift=5e-5)
    with pytest.raises(NumericalInstability, match="drift"):
        run(m, cfg, tmp_path / "hot", progress=False)
    assert (tmp_path / "hot" / FAILURE).exists() and not (tmp_path / "hot" / TRAJECTORY).exists()
    assert run(m, dataclasses.replace(cfg, kT=0.0), tmp_path / "cold", progress=False).exists()


def test_the_self_mobility_measured_from_the_noise_is_the_mobility_diagonal(thermal):
    """E|J dU|^2 / (2 kT dt) per component is diag(M) (fluctuation-dissipation at each marker): 64 draws of
    126 components, relative sampling sd ~1.6%, so 5% is 3 sd; a factor of 2 (the 2 in 2 kT) cannot pass."""
    from vesicle_core.solver.fluctuations import mobility_matrix

    s, integ, X, _ = thermal
    exact = float(np.mean(np.diag(mobility_matrix(integ.mobility, s.be.asnumpy(X)))))
    measured = integ.thermal.self_mobility(X, n_draws=64)
    assert measured == pytest.approx(exact, rel=0.05)


def test_the_noise_step_limit_caps_the_adaptive_step_at_the_asked_displacement():
    """dt_noise = (noise_step h)^2 / (2 kT m_self): at that step the interpolated noise's rms displacement per
    component is noise_step h (32 draws of 126 components: ~2% sampling sd); next_dt never exceeds it; kT = 0 has no
    such limit."""
    import dataclasses

    from vesicle_core.solver.fluctuations import ThermalNoise
    from vesicle_core.solver.trajectory import State

    m = Mm.make_vesicle("icosphere", level=1, axes=(1.0, 0.9, 1.0))
    cfg = unit_run(chi=0.0, stretch=0.0, N=16, scheme="inextensible", tension_space="harmonic", tension_l_max=3,
                    kT=KT, noise_seed=11, noise_step=0.05)
    s = IBMSolver(m.faces, m.vertices, cfg)
    integ = Inextensible(s, 1.0, X0=m.vertices)
    dt = integ.dt_noise
    assert 0 < dt < 1.0
    X = s.xp.asarray(m.vertices)
    noise = ThermalNoise(s.stokes, KT, seed=5)  # another key than the measurement's
    integ.mobility.prepare(X)
    disp = [s.be.asnumpy(integ.mobility.coupler.interpolate(noise.displacement(dt, k))) for k in range(32)]
    assert float(np.sqrt(np.mean(np.square(disp)))) == pytest.approx(0.05 * cfg.h, rel=0.06)
    _, geo = s.forces(X)
    assert integ.next_dt(State(X=X), geo) <= dt
    cold = Inextensible(IBMSolver(m.faces, m.vertices, dataclasses.replace(cfg, kT=0.0)), 1.0, X0=m.vertices)
    assert cold.dt_noise == np.inf


def test_noise_step_outside_its_range_is_refused():
    for bad in (0.0, -0.1, 1.5):
        with pytest.raises(ConfigError, match=r"noise_step must lie in \(0.0, 1.0\]"):
            unit_run(noise_step=bad)
