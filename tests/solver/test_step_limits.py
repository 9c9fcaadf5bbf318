"""The inextensible scheme's step limit on the linearised constraint (``dt_strain``): what it measures is the
second-order area change of one step, so it must scale as dt^2, vanish at first order, and keep a run's held strain
near the tolerance it is given."""

import numpy as np
import pytest
import xarray as xr
from unit_run import unit_run

from vesicle_core.geometry import mesh as Mm
from vesicle_core.solver import membrane as B
from vesicle_core.solver.integrators import Inextensible
from vesicle_core.solver.mobility import IBMSolver
from vesicle_core.solver.simulate import run
from vesicle_core.solver.tension_harmonic import HarmonicSpace
from vesicle_core.solver.trajectory import State


@pytest.mark.parametrize("cg_tol", [1e-11, 1e-4])
@pytest.mark.parametrize("space", ["triangle", "harmonic"])
def test_linearisation_strain_is_second_order_in_the_step(space, cg_tol):
    """One step from the same state with dt and dt / 2: the held strain it adds beyond first order falls 4x, also
    when the CG stops early (cg_tol 1e-4): its residual, which does not shrink with dt, is not part of the estimate
    (with it, the limit collapsed the elongated vesicle's step)."""
    m = Mm.make_vesicle("quasiuniform", n_vertices=162, axes=(1.0, 0.8, 1.0))
    cfg = unit_run(chi=50.0, N=16, scheme="inextensible", tension_space=space, cg_tol=cg_tol, cg_maxiter=500,
                    mesh_ale="area" if space == "harmonic" else "none")  # the ALE's own motion is not counted
    s = IBMSolver(m.faces, m.vertices, cfg)
    integ = Inextensible(s, 1.0, X0=m.vertices)
    X = s.xp.asarray(m.vertices)
    F, geo = s.forces(X)
    errs = []
    for dt in (8e-4, 4e-4, 2e-4):
        state = State(X=X)
        integ.step(state, X, F, geo, dt, 50.0)
        errs.append(state.strain_err)
    assert errs[-1] > 1e-7  # well above the CG's residual and round-off
    for a, b in zip(errs[:-1], errs[1:], strict=True):
        assert 3.3 < a / b < 4.7, errs  # dt^2 (a first-order error would halve)


def test_dt_strain_bounds_the_held_strain_of_a_run(tmp_path):
    """A harmonic run with a tight dt_strain keeps its projected strain within that tolerance of the compliance's in
    every frame and takes more steps than with the limit off (dt_strain = 1)."""
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    base = dict(chi=50.0, N=16, scheme="inextensible", tension_space="harmonic", stretch=0.3, t_end=0.2,
                output_every=0.05, cg_tol=1e-9)
    out = {}
    for tol in (1.0, 2e-5):
        ds = xr.open_dataset(run(m, unit_run(dt_strain=tol, **base), tmp_path / str(tol), progress=False)).load()
        X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
        topo = B.Topology(m.faces, m.n_vertices)
        a0 = B.geometry(X[0], topo).area
        space = HarmonicSpace(m.vertices, m.faces, a0, int(ds.attrs["tension_l_used"]))
        lam = ds.attrs["Lambda_eff"]
        worst = max(np.abs(space.project_faces(B.geometry(X[k], topo).area / a0 - 1)
                           - ds.face_tension.values[k].astype(float) / lam).max() for k in range(1, X.shape[0]))
        out[tol] = (int(ds.attrs["steps"]), worst)
    (steps_off, worst_off), (steps_on, worst_on) = out[1.0], out[2e-5]
    assert worst_off > 2e-5  # the limit has something to do here
    assert worst_on <= 2e-5 * 1.5  # one step's growth of dt past the estimate at most
    assert steps_on > steps_off


def test_a_collapsing_step_stops_the_run_and_names_its_limit(tmp_path, monkeypatch):
    """A step-size error that does not shrink with dt (as on a folded mesh) drives dt_strain's limit down
    geometrically. The run must stop with NumericalInstability once the step falls below DT_COLLAPSE of the bending
    limit, naming the limit that set it, instead of creeping on (the elongated 256^3 run took 700 steps of 3e-12
    tau)."""
    from vesicle_core.errors import NumericalInstability

    monkeypatch.setattr(Inextensible, "linearisation_strain", lambda self, X, dX: 1.0)  # 500x dt_strain, fixed
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    cfg = unit_run(chi=50.0, N=16, scheme="inextensible", tension_space="harmonic", stretch=0.3, t_end=0.2,
                    output_every=0.05)
    with pytest.raises(NumericalInstability, match=r"collapsed .* \(set by the strain limit\)"):
        run(m, cfg, tmp_path / "run", progress=False)


def test_the_bending_limit_is_re_measured_on_the_current_shape():
    """The warm-started re-measurement agrees with a cold measurement at the same shape, on the start's shape
    and on a roughened one whose limit is much shorter (as a wrinkled vesicle's is); next_dt uses it."""
    from vesicle_core.solver.integrators import BENDING_REFRESH
    from vesicle_core.solver.step_size import stability_dt

    m = Mm.make_vesicle("quasiuniform", n_vertices=162, axes=(1.0, 0.8, 1.0))
    cfg = unit_run(chi=50.0, N=16, scheme="inextensible", tension_space="triangle", dt_safety=0.5)
    s = IBMSolver(m.faces, m.vertices, cfg)
    dt0, _ = stability_dt(s, s.xp.asarray(m.vertices))
    integ = Inextensible(s, dt0, X0=m.vertices)
    state = State(X=s.xp.asarray(m.vertices), step=BENDING_REFRESH)
    F, geo = s.forces(state.X)
    assert integ.next_dt(state, geo) <= 0.5 * state.dt_bending * (1 + 1e-12)
    assert state.dt_bending == pytest.approx(dt0, rel=0.05)
    rough = m.vertices * (1.0 + 0.2 * np.random.default_rng(0).standard_normal((m.n_vertices, 1)))
    cold, _ = stability_dt(s, s.xp.asarray(rough))
    assert cold < 0.5 * dt0  # the roughened shape is stiffer: the check below can tell the two apart
    state.X, state.step = s.xp.asarray(rough), 2 * BENDING_REFRESH
    F, geo = s.forces(state.X)
    integ.next_dt(state, geo)
    assert state.dt_bending == pytest.approx(cold, rel=0.05)
    assert integ.bending_limit(state) == state.dt_bending


def _dense(product, X):
    n = X.size
    J = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1.0
        J[:, j] = np.asarray(product(e.reshape(X.shape))).reshape(-1)
    return J


@pytest.mark.slow  # an eigenvalue study of the linearised velocity (pytest -m slow; CI runs it)
@pytest.mark.parametrize("penalty", [False, True])
def test_the_stiffest_mode_is_the_largest_eigenvalue_of_the_linearised_velocity(penalty):
    """On a non-spherical shape with a 3% volume error (so that the volume penalty pushes with a pressure), with
    bending alone (inextensible) and with the stiffer area penalty (explicit), float64:
    - the Arnoldi iteration finds the largest |eigenvalue| of its own product M dF/dX (dense, column by column) to
      1e-4, from a random start and, in a few solves, from its own vector;
    - that is the largest |eigenvalue| of the whole linearisation d(M(X) F(X))/dX (centred differences of the
      velocity) to 5%: the (dM/dX v) F term it leaves out is of relative size |F| h^3 / kappa, a few % here;
    - without the volume pressure's p Hess(V) v added back it is too large: 1.25x with the area penalty, 10x with
      bending alone (p = 3e5 here)."""
    from vesicle_core.solver.step_size import stiffest_mode, stiffness_product

    m = Mm.make_vesicle("quasiuniform", n_vertices=162, axes=(1.0, 0.8, 1.0))
    cfg = unit_run(chi=50.0, N=16, scheme="explicit" if penalty else "inextensible", dtype="float64")
    s = IBMSolver(m.faces, m.vertices, cfg)
    X = 1.01 * np.asarray(m.vertices, float) * (1 + 0.003 * np.random.default_rng(1).standard_normal((m.n_vertices, 1)))
    own = np.abs(np.linalg.eigvals(_dense(stiffness_product(s, X), X))).max()
    eps = 1e-6
    whole = np.abs(np.linalg.eigvals(_dense(
        lambda e: (s.membrane_velocity(X + eps * e) - s.membrane_velocity(X - eps * e)) / (2 * eps), X))).max()
    lam, v, solves = stiffest_mode(s, X, max_iter=60, rtol=1e-6)
    assert lam == pytest.approx(own, rel=1e-4) and solves < 60
    lam2, _, warm = stiffest_mode(s, X, v0=v, max_iter=60, rtol=1e-6)
    assert lam2 == pytest.approx(own, rel=1e-4) and warm <= 5
    assert lam == pytest.approx(whole, rel=0.05)

    def no_correction(e):
        dF = (s.forces(X + 1e-7 * e)[0] - s.forces(X - 1e-7 * e)[0]) / 2e-7
        return s.induced_displacement(X, dF, 1.0, advance=False)

    assert np.abs(np.linalg.eigvals(_dense(no_correction, X))).max() > 1.2 * whole
