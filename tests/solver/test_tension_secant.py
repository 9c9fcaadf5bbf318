"""The secant (BFGS) tension preconditioner: its algebra on dense matrices, and on the IBM's own harmonic tension."""

import numpy as np
import pytest
from unit_run import unit_run

from vesicle_core.errors import ConfigError
from vesicle_core.solver.tension_harmonic import HarmonicTensionSolver
from vesicle_core.solver.tension_secant import SecantPreconditioner


def _spd(rng, K, cond=1e3):
    Q, _ = np.linalg.qr(rng.standard_normal((K, K)))
    return (Q * np.logspace(0, np.log10(cond), K)) @ Q.T


def test_bfgs_meets_each_secant_equation_and_recovers_the_operator_from_conjugate_directions():
    """R_hat p = y after each update; fed K R-conjugate directions (what one CG solve supplies), R_hat is R."""
    rng = np.random.default_rng(0)
    K = 12
    R, G = _spd(rng, K), _spd(rng, K, cond=10)
    sec = SecantPreconditioner(G, 1e6, np.ones(K, bool))
    sec.start(np.ones(3), np.repeat(np.arange(3), 4))  # a poor start: S G S with S = I
    assert np.allclose(sec.R, G)
    P = []
    for v in rng.standard_normal((K, K)):  # Gram-Schmidt in the R inner product
        for p in P:
            v = v - (p @ R @ v) / (p @ R @ p) * p
        P.append(v)
    for k, p in enumerate(P):
        sec.record(p, R @ p)
        sec.update()
        np.testing.assert_allclose(sec.R @ p, R @ p, rtol=1e-9, atol=1e-9 * np.abs(R @ p).max())
        if k < K - 1:
            assert np.abs(sec.R - R).max() > 1e-6 * np.abs(R).max()  # not there before the last direction
    np.testing.assert_allclose(sec.R, R, rtol=1e-8, atol=1e-8 * np.abs(R).max())
    assert sec.updates == K and sec.skipped == 0
    np.testing.assert_allclose(sec.R, sec.R.T, atol=0)


def test_pairs_without_positive_curvature_are_skipped_and_the_model_stays_positive():
    rng = np.random.default_rng(1)
    K = 8
    R = _spd(rng, K)
    sec = SecantPreconditioner(np.eye(K), 1e6, np.ones(K, bool))
    sec.start(np.ones(1), np.zeros(K, int))
    p = rng.standard_normal(K)
    sec.record(p, -p)  # y.p < 0: no positive-definite update meets it
    sec.record(p, np.zeros(K))
    sec.update()
    assert sec.skipped == 2 and sec.updates == 0 and np.allclose(sec.R, np.eye(K))
    for _ in range(40):  # random (not conjugate) pairs of an SPD operator
        q = rng.standard_normal(K)
        sec.record(q, R @ q)
    sec.update()
    assert np.linalg.eigvalsh(sec.R).min() > 0


def test_preconditioner_solves_the_free_block_and_leaves_the_fixed_coefficients_at_zero():
    rng = np.random.default_rng(2)
    K, dt, lam = 9, 3e-4, 1e5
    free = np.arange(K) > 0  # tension_fixed: l = 0 is not solved for
    G = _spd(rng, K, cond=5)
    sec = SecantPreconditioner(G, lam, free)
    rho, l = np.array([0.0, 2.0, 5.0]), np.array([0, 1, 1, 1, 2, 2, 2, 2, 2])
    sec.start(rho, l)
    s = np.sqrt(np.maximum(rho, 1e-3 * 5.0))[l]
    np.testing.assert_allclose(sec.R, s[:, None] * G * s[None, :])  # the diagonal's own operator; l = 0 floored
    r = rng.standard_normal(K)
    z = sec(r, dt)
    A = dt * sec.R + G / lam
    assert z[0] == 0.0
    np.testing.assert_allclose(A[np.ix_(free, free)] @ z[free], r[free], rtol=1e-10)


def test_secant_solves_agree_with_the_diagonal_and_need_fewer_iterations_on_white_right_hand_sides(setup):
    """A sequence of tension solves whose right-hand sides are new and white each time (a thermal step's): with the
    secant model the answers are the diagonal preconditioner's to the tolerance, and once the model has seen
    the operator the CG needs at most 2 iterations where the diagonal needs more."""
    _, s, _, F, geo, mob, space = setup
    topo, dt, tol = s.membrane.topo, 2e-4, 1e-9
    rng = np.random.default_rng(4)
    solvers = {k: HarmonicTensionSolver(mob, topo, space, 1e6, tol=tol, maxiter=300, secant=k == "secant")
               for k in ("diagonal", "secant")}
    its = {k: [] for k in solvers}
    for _ in range(12):
        err = 1e-3 * rng.standard_normal(geo.area.shape[0]) * geo.area
        out = {}
        for k, ts in solvers.items():
            out[k], _, _ = ts.solve(geo, F, 0.0, err, dt, np.zeros(space.K), seed=0)
            its[k].append(ts.last.iterations)
        scale = np.abs(out["diagonal"]).max()
        assert np.abs(out["secant"] - out["diagonal"]).max() <= 1e-5 * scale
    assert solvers["secant"].secant.updates > space.K
    assert max(its["secant"][-4:]) <= 2 < min(its["diagonal"][-4:])


def test_secant_applies_to_the_harmonic_tension_only():
    with pytest.raises(ConfigError, match="cg_precond 'secant'.*tension_space 'harmonic'"):
        unit_run(scheme="inextensible", tension_space="triangle", cg_precond="secant")
