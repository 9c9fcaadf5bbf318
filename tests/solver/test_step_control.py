"""step_control error (solver/embedded_midpoint.py, solver/step_control.py): the step is second order, its error
estimate is the Euler step's local error, the controller takes more steps and makes a smaller error at a tighter
tolerance, a rejected attempt leaves nothing on the state, and the step record counts the controller's steps."""

import copy

import numpy as np
import pytest
import xarray as xr
from unit_run import unit_run

from vesicle_core.errors import ConfigError
from vesicle_core.geometry import mesh as Mm
from vesicle_core.solver import step_limits
from vesicle_core.solver.embedded_midpoint import EmbeddedMidpoint
from vesicle_core.solver.mobility import IBMSolver
from vesicle_core.solver.schemes import integrator_class
from vesicle_core.solver.simulate import run
from vesicle_core.solver.step_control import MAX_FACTOR, MIN_FACTOR, SAFETY, StepController, WrinkleNorm
from vesicle_core.solver.step_limits import LIMITS
from vesicle_core.solver.trajectory import State

RATE = 5.0


def _setup(step_control="error", space="harmonic", tol=0.05, Lambda=1e12):
    """42 vertices, 16^3 grid, a rigid constraint (Lambda 1e12, cg_tol 1e-12) and no ALE: the step is the ODE's alone
    (as tests/solver/test_midpoint.py). A background flow of rate 5 / tau moves the vesicle within a step. Lambda None:
    the solver's default area-stretch modulus (1e6 here)."""
    m = Mm.make_vesicle("icosphere", level=1, axes=(1.0, 0.8, 1.1))
    extra = {"tension_l_max": 3} if space == "harmonic" else {}
    cfg = unit_run(chi=RATE, stretch=1.0, N=16, scheme="inextensible", tension_space=space, Lambda=Lambda,
                   cg_tol=1e-12, cg_maxiter=2000, mesh_ale="none", dt="power", step_control=step_control,
                   step_tol=tol, **extra)
    s = IBMSolver(m.faces, m.vertices, cfg)
    integ = integrator_class(cfg)(s, 1e-3, X0=m.vertices)
    return s, integ, s.xp.asarray(m.vertices)


def _advance(s, integ, X, dt, n, keep=()):
    """n steps of dt, no controller (adaptive off: never rejects); -> the end, and the positions after the steps
    counted in ``keep``."""
    integ.adaptive = False
    state = State(X=X)
    kept = {}
    for k in range(1, n + 1):
        F, geo = s.forces(state.X)
        state.X = state.X + integ.step(state, state.X, F, geo, dt, RATE)
        state.step += 1
        if k in keep:
            kept[k] = state.X
    return (state.X, kept) if keep else state.X


def test_the_scheme_is_chosen_by_step_control_and_refused_where_it_does_not_apply():
    _, integ, _ = _setup()
    assert isinstance(integ, EmbeddedMidpoint) and integ.strain_order == 3
    _, integ, _ = _setup("limits")
    assert not isinstance(integ, EmbeddedMidpoint)
    with pytest.raises(ConfigError, match="step_control 'error'.*kT = 0.0405"):
        unit_run(scheme="inextensible", tension_space="harmonic", kT=0.0405, step_control="error")
    with pytest.raises(ConfigError, match="step_control 'error'.*dt = 0.001"):
        unit_run(scheme="inextensible", dt=1e-3, step_control="error")
    with pytest.raises(ConfigError, match="step_tol must lie in"):
        unit_run(step_tol=0.0)


def test_the_step_is_second_order_and_the_estimate_is_eulers_local_error():
    """Over a fixed time (4 steps of dt, then 8 of dt / 2) the error against 64 steps of dt / 16 falls ~4x per halved
    dt (second order, global). The error estimate of one step, dt (U_mid - U0), falls ~4x per halving (local
    O(dt^2)) and tends to the forward-Euler step's actual error (X^n + dt U0 against the reference): their relative
    difference, the next order, halves with dt. So it measures the first-order step's error, and the step taken
    (second order) is well inside it. The steps are 0.2 and 0.1 of this mesh's bending limit (2.5e-4 tau), as in
    test_midpoint. A rigid constraint: at a finite Lambda the tension relaxes towards its quasi-static value at rates
    Lambda D M D^T / W that span the step, and the layer after the start (and the reversal) is resolved to first
    order only (docs/explanation/step-control.md)."""
    s, integ, X = _setup()
    errs, est, euler = [], [], []
    for dt in (5e-5, 2.5e-5):
        ref, kept = _advance(s, integ, X, dt / 16, 4 * 16, keep=(16,))
        errs.append(float(np.abs(_advance(s, integ, X, dt, 4) - ref).max()))
        dX = _advance(s, integ, X, dt, 1) - X
        est.append(float(np.abs(integ.estimate).max()))
        # the Euler step from X: the midpoint step less the estimate, X + dt U0
        euler.append(float(np.abs(X + dX - integ.estimate - kept[16]).max()))
    assert 3.2 < errs[0] / errs[1] < 4.8, errs
    assert 3.2 < est[0] / est[1] < 4.8, est
    gap = [abs(a / b - 1) for a, b in zip(est, euler, strict=True)]
    assert gap[1] < 0.08 and 0.35 < gap[1] / gap[0] < 0.65, (est, euler)


def test_the_controller_follows_scipys_rules():
    c = StepController(order=1)
    assert c.accept_factor(0.0, False) == MAX_FACTOR
    assert c.accept_factor(0.25, False) == pytest.approx(SAFETY * 2.0)  # err^(-1/2): local error ~ dt^2
    assert c.accept_factor(0.25, True) == 1.0  # no growth right after a rejection
    assert c.reject_factor(4.0) == pytest.approx(SAFETY * 0.5)
    assert c.reject_factor(1e6) == MIN_FACTOR


def test_the_norm_splits_the_shape_from_the_wrinkles():
    """On a sphere of 2562 vertices: a normal displacement of l = 2 lands in the shape band only, one of l = 12 in
    the wrinkle band only, each with its rms; the sphere's radial function has neither band."""
    m = Mm.make_vesicle("icosphere", level=4, axes=(1.0, 1.0, 1.0))
    X = np.asarray(m.vertices)
    n = X / np.linalg.norm(X, axis=1, keepdims=True)
    F = np.asarray(m.faces)
    A = 0.5 * np.linalg.norm(np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]), axis=1)
    w = np.bincount(F.ravel(), weights=np.repeat(A / 3, 3), minlength=len(X))
    norm = WrinkleNorm(X, w, h=0.04, rtol=0.1)
    z = n[:, 2]
    p2 = 1.5 * z ** 2 - 0.5
    from numpy.polynomial import legendre

    p12 = legendre.legval(z, [0] * 12 + [1])
    for f, band in ((p2, 0), (p12, 1)):
        rms = float(np.sqrt(np.sum(w * f ** 2) / w.sum()))
        got = norm.bands(f)
        # the discrete sphere: the two are orthogonal to 1e-4
        assert got[band] == pytest.approx(rms, rel=1e-3) and got[1 - band] < 1e-2 * rms, (band, got, rms)
    D, W = norm.amplitudes(X)
    assert D < 1e-12 and W < 1e-12
    # err: an estimate of 1e-4 R on the l = 12 band against a wrinkle of 1e-2 R: 1e-4 / (atol + 0.1 x 1e-2)
    Xw = X + (1e-2 * p12)[:, None] * n
    err = norm(Xw, n, (1e-4 * p12)[:, None] * n)
    W = norm.amplitudes(Xw)[1]
    assert err == pytest.approx(norm.bands(1e-4 * p12)[1] / (norm.atol + 0.1 * W), rel=1e-9)


def test_a_rejected_attempt_leaves_the_state_as_it_was():
    """An attempt the norm rejects is retried at MIN_FACTOR of its dt: the step, the tension and the warm-start history
    are those of a fresh integrator's step at the shorter dt from a copy of the same state, and the record moves the
    step to the error limit with the retried dt."""
    s, integ, X = _setup()
    fresh = _setup()[1]
    integ.adaptive = False
    state = State(X=X)
    F, geo = s.forces(X)
    state.X = X + integ.step(state, X, F, geo, 2e-5, RATE)  # one step first: the warm start then has a history
    state.step = 1
    other = copy.deepcopy(state)
    calls = []

    def reject_first(*args):
        calls.append(args)
        return 1e6 if len(calls) == 1 else 0.5

    integ.norm, integ.adaptive = reject_first, True
    step_limits.record(state, {"bending": 1.0, "error": 3e-5}, "error")
    state.limit_last = LIMITS.index("bending")  # as if bending had set it: the rejection moves the count
    state.limit_counts = [0] * len(LIMITS)
    state.limit_counts[LIMITS.index("bending")] = 1
    F, geo = s.forces(state.X)
    dX = integ.step(state, state.X, F, geo, 3e-5, RATE)
    dt = integ.taken(3e-5)
    assert len(calls) == 2 and integ.rejected == 1 and dt == pytest.approx(3e-5 * MIN_FACTOR, rel=1e-15)
    assert state.limit_last == LIMITS.index("error") and state.limit_dt[LIMITS.index("error")] == dt
    assert state.limit_counts[LIMITS.index("error")] == 1 and sum(state.limit_counts) == 1
    assert state.dt_error == pytest.approx(dt)  # no growth right after a rejection (err 0.5 would allow 1.27 dt)
    fresh.adaptive = False
    F2, geo2 = s.forces(other.X)
    dX2 = fresh.step(other, other.X, F2, geo2, dt, RATE)
    scale = float(np.abs(dX2).max())
    np.testing.assert_allclose(np.asarray(dX), np.asarray(dX2), rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(np.asarray(state.sigma), np.asarray(other.sigma), rtol=1e-6,
                               atol=1e-8 * float(np.abs(other.sigma).max()))
    assert state.dt_steps == other.dt_steps == (2e-5, dt)


@pytest.mark.slow  # three runs, ~30 s on an idle machine (pytest -m slow; CI runs it)
def test_a_tighter_tolerance_takes_more_steps_and_errs_less(tmp_path):
    """A flowing 16^3 run (162 vertices) at tolerances tight enough that the controller sets every step: a 4x tighter
    step_tol takes ~2x the steps (the estimate is O(dt^2)) and the final shape's distance from a run at a 64x tighter
    one falls ~4x (the step is second order: the error goes as dt^2, so as step_tol). A rigid constraint (Lambda
    1e12): at the default Lambda the error after the reversal fell only 2-3x per 4x (the tension's rate estimate
    restarts there; docs/explanation/step-control.md)."""
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    base = dict(chi=50.0, N=16, scheme="inextensible", tension_space="harmonic", stretch=0.2, t_end=0.2,
                output_every=0.05, dt="power", dt_safety=0.5, kT=0.0, mesh_ale="none", step_control="error",
                Lambda=1e12, cg_tol=1e-10, checkpoint_every=10_000)
    out = []
    for tol in (4e-4, 1e-4, 6.25e-6):
        ds = xr.open_dataset(run(m, unit_run(**base, step_tol=tol), tmp_path / str(tol), progress=False)).load()
        X = np.stack([ds[f"node_{c}"].values[-1] for c in "xyz"], axis=1)
        out.append((ds.attrs["steps"], X, int(ds.steps_error.sum())))
    (n1, X1, e1), (n2, X2, e2), (n3, X3, _) = out
    assert e1 == n1 and e2 == n2  # the controller sets every step here
    assert 1.7 < n2 / n1 < 2.3 and n3 > n2, (n1, n2, n3)
    d1, d2 = float(np.abs(X1 - X3).max()), float(np.abs(X2 - X3).max())
    assert 2.5 < d1 / d2 < 6.0, (d1, d2)
