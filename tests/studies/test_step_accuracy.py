"""studies/step_accuracy.py measures what it says: known differences put into synthetic spectra come back out."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

spec = importlib.util.spec_from_file_location("step_accuracy", Path(__file__).resolve().parents[2] / "studies" /
                                              "step_accuracy.py")
SA = importlib.util.module_from_spec(spec)
spec.loader.exec_module(SA)


def spectra(t_star, l_star, scale=1.0, sigma_shift=0.0, time=None):
    time = np.linspace(-0.1, 0.5, 31) if time is None else time
    ls = np.arange(0, 41)
    D = (1e-3 * (1.0 + 50.0 * (time - 0.2) ** 2))[:, None] * np.exp(-0.05 * ls)[None, :] * scale
    return xr.Dataset({"Delta_l": (("time", "l"), D), "sigma": ("time", -100.0 + 300.0 * time + sigma_shift),
                       "t_star_fit": t_star, "l_star_fit": l_star}, coords={"time": time, "l": ls})


def test_identical_runs_differ_by_nothing():
    r = SA.compare(spectra(0.2, 13.0), spectra(0.2, 13.0))
    assert r["l_star_rel"] == 0 and r["t_star_diff"] == 0
    assert r["delta2_rms_rel"] < 1e-12 and r["sigma_rms_rel"] == 0 and r["delta_l_max_rel"] < 1e-12


def test_known_differences_are_measured():
    ref = spectra(0.2, 13.0)
    r = SA.compare(ref, spectra(0.205, 13.13, scale=1.1, sigma_shift=2.0))
    assert r["l_star_rel"] == pytest.approx(0.01)
    assert r["t_star_diff"] == pytest.approx(0.005)
    assert r["delta2_rms_rel"] == pytest.approx(0.1)  # Delta_2 scaled by 1.1 at every frame
    sr = ref["sigma"].values[(ref.time.values >= 0) & (ref.time.values <= 0.5)]
    assert r["sigma_rms_rel"] == pytest.approx(2.0 / np.sqrt(np.mean(sr ** 2)))
    # Delta_l at each run's own t_*: the 1.1 scale, and the candidate's t_* a quarter of the way from the frame at
    # 0.20 (Delta_l x 1) to the one at 0.22 (x 1.02), log-linear between them
    expect = 1.1 * 1.02 ** 0.25 - 1.0
    assert r["delta_l_max_rel"] == pytest.approx(expect, rel=1e-3)


def test_other_frame_times_are_interpolated():
    ref = spectra(0.2, 13.0)
    cand = spectra(0.2, 13.0, time=np.linspace(-0.1, 0.5, 61))  # twice the frames: same curves
    r = SA.compare(ref, cand)
    assert r["delta2_rms_rel"] < 1e-3 and r["sigma_rms_rel"] < 1e-12
