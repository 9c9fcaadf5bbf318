"""The inextensible scheme's stochastic midpoint variant (noise_scheme midpoint; solver/midpoint.py): second order
without noise, the Brownian increment's covariance 2 kT dt N over a step, the Ito drift kT div N in the mean, and
clear errors."""

import numpy as np
import pytest

from vesicle_core.errors import ConfigError
from vesicle_core.geometry import mesh as Mm
from vesicle_core.model.run_config import RunConfig
from vesicle_core.solver.fluctuations import mobility_divergence
from vesicle_core.solver.integrators import Inextensible, integrator_class
from vesicle_core.solver.midpoint import MidpointInextensible
from vesicle_core.solver.mobility import IBMSolver
from vesicle_core.solver.trajectory import State

KT = 0.0405


def _setup(noise_scheme, kT=0.0, space="harmonic", drift_every=1):
    """42 vertices, 16^3 grid, a rigid constraint (Lambda 1e12, cg_tol 1e-12) and no ALE: the step is the ODE's (or
    SDE's) alone. A background flow of rate 5 / tau moves the vesicle within a step."""
    m = Mm.make_vesicle("icosphere", level=1, axes=(1.0, 0.8, 1.1))
    extra = {"tension_l_max": 3} if space == "harmonic" else {}
    cfg = RunConfig(chi=5.0, stretch=1.0, N=16, scheme="inextensible", tension_space=space, Lambda=1e12,
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
        RunConfig(scheme="explicit", noise_scheme="midpoint")


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
