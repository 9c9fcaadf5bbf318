"""The per-frame record of what set each time step (step_limits): the recorded limit is the one that allowed the
shortest step, the counts add up to the run's steps, and recording it changes no number of the run."""

import math

import numpy as np
import pytest
import xarray as xr

from vesicle_core.geometry import mesh as Mm
from vesicle_core.model.run_config import RunConfig
from vesicle_core.solver import simulate, step_limits
from vesicle_core.solver.simulate import run
from vesicle_core.solver.step_limits import LIMITS, shares_line
from vesicle_core.solver.trajectory import State, TrajectoryWriter

# every run parameter the checks rely on, set here (the library's defaults may move)
ADAPTIVE = dict(chi=50.0, N=16, scheme="inextensible", tension_space="harmonic", stretch=0.3, t_end=0.2,
                output_every=0.05, dt="power", dt_safety=0.5, dt_growth=0.1, dt_strain=2e-3, kT=0.0,
                mesh_ale="none", checkpoint_every=10_000)


@pytest.fixture(scope="module")
def adaptive_run(tmp_path_factory):
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    path = run(m, RunConfig(**ADAPTIVE), tmp_path_factory.mktemp("rec"), progress=False)
    return m, xr.open_dataset(path).load()


def _dts(ds):
    return np.stack([ds[f"dt_limit_{k}"].values for k in LIMITS], axis=1)


def test_the_recorded_limit_is_the_argmin_of_the_recorded_allowed_steps(adaptive_run):
    _, ds = adaptive_run
    code, dts = ds.step_limit.values.astype(int), _dts(ds)
    assert code[0] == -1 and np.isnan(dts[0]).all()  # the first frame comes before any step
    assert (code[1:] >= 0).all()
    np.testing.assert_array_equal(code[1:], np.nanargmin(dts[1:], axis=1))
    assert np.isnan(dts[1:, LIMITS.index("fixed")]).all() and np.isnan(dts[1:, LIMITS.index("noise_step")]).all()
    assert np.isnan(dts[1:, LIMITS.index("event")]).all()  # several steps between frames here: never set by them
    for name in ("bending", "flow"):  # these apply at every step of a flowing run
        assert np.isfinite(ds[f"dt_limit_{name}"].values[1:]).all(), name
    # growth: where a mode grows, after the reversal (the compressing flow makes the tension negative); none
    # grows under the stretching flow's positive tension
    grows = ds.dt_limit_growth.values
    assert np.isfinite(grows[-1]) and np.isnan(grows[1:][ds.tension.values[1:] > 0]).all()
    # the step taken lands on the frames in equal steps: never longer than the binding limit allows
    allowed = np.nanmin(dts[1:], axis=1)
    assert (ds.dt_tau.values[1:] <= allowed * (1 + 1e-12)).all()
    # the flow limit is 0.1 dt_growth / chi, exactly
    assert ds.dt_limit_flow.values[1:] == pytest.approx(0.1 * 0.1 / 50.0, rel=1e-15)


def test_the_counts_add_up_to_the_steps_and_hold_the_last_steps_limit(adaptive_run):
    _, ds = adaptive_run
    counts = np.stack([ds[f"steps_{k}"].values for k in LIMITS], axis=1)
    assert counts[0].sum() == 0
    assert counts.sum() == ds.attrs["steps"] > 0
    assert (counts[1:].sum(axis=1) >= 1).all()  # a step between any two frames
    code = ds.step_limit.values.astype(int)
    assert all(counts[k, code[k]] >= 1 for k in range(1, len(code)))
    assert counts[:, LIMITS.index("fixed")].sum() == 0


def test_recording_changes_no_number_of_the_run(adaptive_run, tmp_path, monkeypatch):
    """The same run with the recording switched off gives the same positions, tensions and steps, bit for bit."""
    m, ds = adaptive_run
    monkeypatch.setattr(simulate.step_limits, "record", lambda *args: None)
    off = xr.open_dataset(run(m, RunConfig(**ADAPTIVE), tmp_path / "off", progress=False)).load()
    assert (off.step_limit.values == -1).all()  # the switch worked
    assert off.attrs["steps"] == ds.attrs["steps"]
    for name in ("node_x", "node_y", "node_z", "face_tension", "dt_tau", "tension"):
        np.testing.assert_array_equal(off[name].values, ds[name].values, err_msg=name)


def test_frames_closer_than_the_step_set_it(tmp_path):
    """Frames closer together than every limit allows: each step goes to the next frame in one, recorded as the
    event limit, with the time that was left as its allowed step."""
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    cfg = RunConfig(**{**ADAPTIVE, "stretch": 0.01, "t_end": 0.01, "output_every": 0.001})
    ds = xr.open_dataset(run(m, cfg, tmp_path, progress=False)).load()
    assert (ds.step_limit.values[1:] == LIMITS.index("event")).all()
    assert int(ds.steps_event.sum()) == ds.attrs["steps"] == ds.sizes["time"] - 1
    np.testing.assert_allclose(ds.dt_limit_event.values[1:], ds.dt_tau.values[1:], rtol=1e-9)
    np.testing.assert_array_equal(ds.step_limit.values[1:], np.nanargmin(_dts(ds)[1:], axis=1))


def test_a_fixed_step_run_records_the_fixed_limit(tmp_path):
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    cfg = RunConfig(chi=20.0, N=16, scheme="explicit", dt=2e-5, stretch=0.02, t_end=0.02, output_every=0.01,
                    Lambda=2e4, K_volume=1e6)
    ds = xr.open_dataset(run(m, cfg, tmp_path, progress=False)).load()
    assert (ds.step_limit.values[1:] == LIMITS.index("fixed")).all()
    np.testing.assert_array_equal(ds.dt_limit_fixed.values[1:], 2e-5)
    assert int(ds.steps_fixed.sum()) == ds.attrs["steps"] > 0


def test_record_rejects_unknown_limits_and_drops_unbounded_ones():
    state = State(X=None)
    step_limits.record(state, {"bending": 2.0, "noise_step": math.inf, "growth": 1.0}, "growth")
    assert state.limit_last == LIMITS.index("growth")
    assert math.isnan(state.limit_dt[LIMITS.index("noise_step")]) and state.limit_dt[LIMITS.index("bending")] == 2.0
    sc = step_limits.frame_scalars(state)
    assert sc["steps_growth"] == 1 and sc["step_limit"] == LIMITS.index("growth")
    assert step_limits.frame_scalars(state)["steps_growth"] == 0  # counted once, in the frame after the step
    with pytest.raises(ValueError, match="unknown step limit"):
        step_limits.record(state, {"wobble": 1.0}, "wobble")
    assert set(TrajectoryWriter.LIMIT_VARS) <= set(TrajectoryWriter.FRAME_VARS)


def test_shares_line():
    assert shares_line({"bending": 71, "growth": 20, "flow": 9, "tension": 0}) == \
        "steps: 100 (bending 71%, growth 20%, flow 9%)"
    assert shares_line({}) == "steps: 0"
