"""Validation helpers: the periodic-box comparison (Table I) and the report builder."""

import numpy as np
import pytest
import xarray as xr

from vesicle_core import mesh as M
from vesicle_core.datasets import spectra_from_trajectory
from vesicle_core.simulate import RunConfig, run
from vesicle_core.theory import run_theory
from vesicle_core.validation import box_comparison, collect, render, stage1_growth


@pytest.fixture(scope="module")
def box_runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("box")
    m = M.make_vesicle("icosphere", level=2)
    out = {}
    for N, L in ((16, 5.0), (24, 7.5)):  # same h = 0.3125
        cfg = RunConfig(chi=10.0, N=N, L=L, stretch=0.2, t_end=0.2, output_every=0.05, scheme="projection", dt=2.5e-4)
        out[L] = run(m, cfg, d / f"L{L}", progress=False)
    return out


def test_identical_runs_have_zero_box_error(box_runs):
    with xr.open_dataset(box_runs[5.0]) as a:
        b = box_comparison(a.load(), a.load())
    assert b["max_shape_error"] == 0 and b["max_velocity_error"] == 0


def test_larger_box_changes_shape_little(box_runs):
    with xr.open_dataset(box_runs[5.0]) as a, xr.open_dataset(box_runs[7.5]) as b:
        r = box_comparison(a.load(), b.load())
    # 2.5 vs 3.75 diameters: the image interaction is weak but not zero
    assert 0 < r["max_shape_error"] < 0.02
    assert r["L_small"] == 5.0 and r["L_large"] == 7.5


def test_report_from_real_files(box_runs, tmp_path):
    with xr.open_dataset(box_runs[5.0]) as t:
        spec = spectra_from_trajectory(t.load(), l_max=8)
    sp = tmp_path / "spectra.nc"
    spec.to_netcdf(sp)
    th = tmp_path / "theory.nc"
    run_theory(0.116, 150.0, n_out=50, store_modes=False).to_netcdf(th)
    manifest = {"cases": [{"case_id": "c1", "group": "fine", "trajectory": str(box_runs[5.0]), "spectra": str(sp),
                           "theory": str(th)}],
                "box": {"small": str(box_runs[5.0]), "large": str(box_runs[7.5])},
                "figures": [{"path": "fig.png", "caption": "a figure"}]}
    text = render(manifest, collect(manifest))
    for word in ("Characteristic wrinkle mode", "Periodic box", "Conservation", "differs from the paper", "fig.png"):
        assert word in text
    assert np.isfinite(stage1_growth(spec)) or np.isnan(float(spec.t_star))
