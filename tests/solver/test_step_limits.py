"""The inextensible scheme's step limit on the linearised constraint (``dt_strain``): what it measures is the
second-order area change of one step, so it must scale as dt^2, vanish at first order, and keep a run's held strain
near the tolerance it is given."""

import numpy as np
import pytest
import xarray as xr

from vesicle_core.geometry import mesh as Mm
from vesicle_core.model.run_config import RunConfig
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
    cfg = RunConfig(chi=50.0, N=16, scheme="inextensible", tension_space=space, cg_tol=cg_tol, cg_maxiter=500,
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
        ds = xr.open_dataset(run(m, RunConfig(dt_strain=tol, **base), tmp_path / str(tol), progress=False)).load()
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
    cfg = RunConfig(chi=50.0, N=16, scheme="inextensible", tension_space="harmonic", stretch=0.3, t_end=0.2,
                    output_every=0.05)
    with pytest.raises(NumericalInstability, match=r"collapsed .* \(set by the dt_strain limit\)"):
        run(m, cfg, tmp_path / "run", progress=False)


def test_the_bending_limit_is_re_measured_on_the_current_shape():
    """The warm-started re-measurement agrees with a cold power iteration at the same shape, on the start's shape
    and on a roughened one whose limit is much shorter (as a wrinkled vesicle's is); next_dt uses it."""
    from vesicle_core.solver.integrators import BENDING_REFRESH
    from vesicle_core.solver.step_size import power_dt

    m = Mm.make_vesicle("quasiuniform", n_vertices=162, axes=(1.0, 0.8, 1.0))
    cfg = RunConfig(chi=50.0, N=16, scheme="inextensible", tension_space="triangle", dt_safety=0.5)
    s = IBMSolver(m.faces, m.vertices, cfg)
    dt0, _ = power_dt(s, s.xp.asarray(m.vertices))
    integ = Inextensible(s, dt0, X0=m.vertices)
    state = State(X=s.xp.asarray(m.vertices), step=BENDING_REFRESH)
    F, geo = s.forces(state.X)
    assert integ.next_dt(state, geo) <= 0.5 * state.dt_bending * (1 + 1e-12)
    assert state.dt_bending == pytest.approx(dt0, rel=0.05)
    rough = m.vertices * (1.0 + 0.2 * np.random.default_rng(0).standard_normal((m.n_vertices, 1)))
    cold, _ = power_dt(s, s.xp.asarray(rough))
    assert cold < 0.5 * dt0  # the roughened shape is stiffer: the check below can tell the two apart
    state.X, state.step = s.xp.asarray(rough), 2 * BENDING_REFRESH
    F, geo = s.forces(state.X)
    integ.next_dt(state, geo)
    assert state.dt_bending == pytest.approx(cold, rel=0.05)
    assert integ.bending_limit(state) == state.dt_bending
