"""The inextensible scheme's stochastic midpoint variant (noise_scheme midpoint; solver/midpoint.py): second order
without noise, the Brownian increment's covariance 2 kT dt N over a step, the Ito drift kT div N in the mean, and
clear errors."""

import numpy as np
import pytest
from unit_run import unit_run

from vesicle_core.errors import ConfigError
from vesicle_core.geometry import mesh as Mm
from vesicle_core.solver.fluctuations import mobility_divergence
from vesicle_core.solver.integrators import Inextensible
from vesicle_core.solver.midpoint import MidpointInextensible
from vesicle_core.solver.mobility import IBMSolver
from vesicle_core.solver.schemes import integrator_class
from vesicle_core.solver.trajectory import State

KT = 0.0405


def _setup(noise_scheme, kT=0.0, space="harmonic", drift_every=1):
    """42 vertices, 16^3 grid, a rigid constraint (Lambda 1e12, cg_tol 1e-12) and no ALE: the step is the ODE's (or
    SDE's) alone. A background flow of rate 5 / tau moves the vesicle within a step."""
    m = Mm.make_vesicle("icosphere", level=1, axes=(1.0, 0.8, 1.1))
    extra = {"tension_l_max": 3} if space == "harmonic" else {}
    cfg = unit_run(chi=5.0, stretch=1.0, N=16, scheme="inextensible", tension_space=space, Lambda=1e12,
                    cg_tol=1e-12, cg_maxiter=2000, kT=kT, noise_seed=7, noise_scheme=noise_scheme, mesh_ale="none",
                    noise_drift_every=drift_every, **extra)
    s = IBMSolver(m.faces, m.vertices, cfg)
    integ = integrator_class(cfg)(s, 1e-3, X0=m.vertices)
    return s, integ, s.xp.asarray(m.vertices)


def _advance(s, integ, X, dt, n, rate=5.0, step0=0):
    state = State(X=X, step=step0)
    for _ in range(n):
        F, geo = s.forces(state.X)
        state.X = state.X + integ.step(state, state.X, F, geo, dt, rate)
        state.step += 1
    return state.X


def test_the_midpoint_variant_is_chosen_by_noise_scheme_and_refused_elsewhere():
    _, integ, _ = _setup("midpoint")
    assert isinstance(integ, MidpointInextensible) and integ.strain_order == 3
    _, integ, _ = _setup("lm")
    assert type(integ) is Inextensible and integ.strain_order == 2
    with pytest.raises(ConfigError, match="noise_scheme 'midpoint'.*scheme 'inextensible'.*got scheme 'explicit'"):
        unit_run(scheme="explicit", noise_scheme="midpoint")


@pytest.mark.parametrize("space", ["harmonic", "triangle"])
def test_without_noise_the_midpoint_is_second_order_and_euler_first(space):
    """One step's error against 32 midpoint steps of dt / 32 falls ~8x per halved dt (local error O(dt^3)) with the
    midpoint, ~4x with forward Euler (O(dt^2)); and at the same dt the midpoint's error is the smaller. The steps are
    0.2 and 0.1 of this mesh's bending limit (2.5e-4 tau): near the limit the stiffest mode's error dominates both."""
    s, mid, X = _setup("midpoint", space=space)
    _, eul, _ = _setup("euler", space=space)
    err = {"midpoint": [], "euler": []}
    for dt in (5e-5, 2.5e-5):
        ref = _advance(s, mid, X, dt / 32, 32)
        for name, integ in (("midpoint", mid), ("euler", eul)):
            err[name].append(float(np.abs(_advance(s, integ, X, dt, 1) - ref).max()))
    m, e = err["midpoint"], err["euler"]
    assert 6.0 < m[0] / m[1] < 10.0, err
    assert 3.0 < e[0] / e[1] < 5.0, err
    assert m[1] < 0.2 * e[1], err


@pytest.mark.slow  # a sampling study: the mean drift over many steps (pytest -m slow; CI runs it)
@pytest.mark.parametrize("drift_every", [1, 0])
def test_the_midpoint_step_drifts_by_kT_div_N_in_the_mean(drift_every):
    """Weak consistency with the Ito equation: the mean of a noisy midpoint step, less the Euler step with the same
    Brownian increment and no drift and less the two schemes' deterministic difference, is kT div_X N dt, N the
    constrained mobility and its divergence measured by central differences (mobility_divergence, 252 constrained
    solves). The pairing cancels the noise to first order, so 1000 draws give the drift within ~3%: the regression
    slope on kT div N dt is 1 within 0.15 (5 standard errors); a corrector that projects its noise at X^n instead of
    the predicted midpoint gave 0.08. Without the random finite difference of the spreading (drift_every 0) the slope
    is 1 too: here the drift comes from the constraint's projection P and the interpolation J, the left-hand factor
    the corrector evaluates at the midpoint; J A d(S P^T) is below the sampling error (slopes 0.983 and 0.976 +-
    0.021 with and without it, 2000 draws): with a translation-invariant kernel sum_k d S / d X_k spreads the
    gradient of a scalar field, which the Stokes solve's Leray projector removes up to the difference between the
    kernel's exact and the grid's discrete gradient."""
    dt = 1e-4
    s, integ, X = _setup("midpoint", kT=KT, drift_every=drift_every)
    _, det, _ = _setup("midpoint")
    _, eul, _ = _setup("euler")
    th = integ.thermal
    F, geo = s.forces(X)
    th.constrained.dt, th.constrained.step = dt, 0
    expected = KT * dt * mobility_divergence(th.constrained, np.asarray(X))
    d0 = det.step(State(X=X), X, F, geo, dt, 0.0) - eul.step(State(X=X), X, F, geo, dt, 0.0)
    zero = np.zeros(geo.area.shape[0])
    diffs = []
    for k in range(1000):
        mid = integ.step(State(X=X, step=k), X, F, geo, dt, 0.0)
        half1, half2 = th.half_increments(dt, k)
        integ.mobility.prepare(X)
        u = integ.mobility.coupler.interpolate(half1 + half2) / dt
        U = integ.tension_solve(State(X=X), geo, F, u, zero, dt, zero, None, None)[2]
        diffs.append(np.asarray(mid - U * dt - d0))
    diffs = np.array(diffs)
    mean, se = diffs.mean(0), diffs.std(0) / np.sqrt(len(diffs))
    slope = float((mean * expected).sum() / (expected**2).sum())
    slope_se = float(np.sqrt(((se * expected) ** 2).sum()) / (expected**2).sum())
    assert slope_se < 0.05, slope_se  # the check has the power to see the drift
    assert abs(slope - 1.0) < 0.15, (slope, slope_se)
