"""Every discretisation a shipped config uses, run on the strict CuPy stand-in (tests/strict_cupy.py) against NumPy.

The stand-in's device arrays refuse every implicit conversion (``np.asarray``, ``float()``, NumPy functions, host
arrays mixed in), so a run that finishes on it has no hidden host round trip, and its transfer counts are those a
GPU would make. Each case is a few steps of a 162-vertex vesicle at N = 16 (the default job's discretisation and the
variants of config/*.yaml: the shape ALE of the elongated cases, the lm and midpoint noise schemes with the secant
preconditioner, the projection scheme and the paper's explicit one, a resume from a checkpoint, and ``vesicle
decompose`` of the result), so each takes seconds.

Tolerance. The CuPy path differs from NumPy's in the order of floating-point operations only: ``xp.fft`` instead of
pyFFTW/scipy, the complex spectral layout instead of the interleaved one, a scatter-add instead of numba's loop: in
float64 ~1e-16 relative per operation. The runs then agree to ATOL = 1e-9 R, the mesh ALE's too (CG converged to
1e-10, so its stopping test cannot pick different iteration counts; the ALE's least squares solved exactly, a
Lipschitz map with condition ~5e5: tests/solver/test_mesh_ale.py). Measured: 2.2e-16 R without the ALE, 2.7e-14 R
with mesh_ale quality, 4.7e-16 R with shape. (Until 2026-12-08 the ALE stopped LSQR at 100 iterations, short of the
minimiser, which amplified round-off ~1e10 in one step: 9.8e-6 R and 3.1e-6 R here, compared to 1e-4 R.) float32
grid fields (round-off 1e-7 instead of 1e-16) are compared to ATOL_FLOAT32 = 1e-7 R (measured 4.3e-9 R) and their
tension to 1e-4 of its largest value (measured 2.4e-6). A real fault (a sign, a missing term, a stale buffer) moves
the vesicle by far more: the step's own displacement is ~2e-3 R.

Run against real CuPy by ``VESICLE_TEST_REAL_CUPY=1`` (benchmarks/gpu_check.py does): the same comparisons, without
the transfer counts (real CuPy does not count them).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from vesicle_core.geometry import mesh as M

ATOL = 1e-9  # R: see the module docstring
ATOL_FLOAT32 = 1e-7
ROOT = str(Path(__file__).resolve().parents[2])
REAL = os.environ.get("VESICLE_TEST_REAL_CUPY") == "1"

#: the default job's discretisation (config/config.yaml), every run parameter set explicitly: the library's
#: defaults are being changed to these, and a test must not move with them
DEFAULT_JOB = dict(
    chi=20.0, N=16, L=5.0, scheme="inextensible", tension_space="harmonic", tension_l_max=None, mesh_ale="quality",
    coupling="sharp", kernel="bao6", sharp_floor=0.01, seed_spectrum="thermal", seed=0, seed_scale=1.0,
    dt="power", dt_safety=0.8, dt_growth=0.1, dt_strain=2e-3, cg_tol=1e-10, cg_maxiter=2000, cg_precond="auto",
    projection_refresh=10, kT=0.0, Re=0.0, Lambda=None, area_model="voronoi", K_volume=0.0, K_area=0.0,
    stationary_tol=0.0, max_drift=0.05, tension_fixed=None, noise_seed=0, noise_step=0.04, noise_drift_every=1,
    # ~4 steps of forward flow, the thermal seed at the reversal, ~5 steps after it, a frame every ~3 steps
    stretch=0.002, t_end=0.004, output_every=0.002, checkpoint_every=2000, store_velocity=False,
)
NOISE = dict(kT=0.0405, noise_seed=3, noise_step=0.04, noise_drift_every=1, cg_precond="secant",
             seed_spectrum="mesh")

CASES = {
    "default_job_without_ale": dict(mesh_ale="none"),
    "default_job": {},
    "default_job_float32": dict(dtype="float32"),
    "shape_ale": dict(mesh_ale="shape"),
    "noise_lm_secant": dict(NOISE, noise_scheme="lm"),
    "noise_midpoint_secant": dict(NOISE, noise_scheme="midpoint"),
    # the fixed-step schemes: the projection variation of the sweeps and the paper's explicit area penalty
    "projection": dict(scheme="projection", tension_space="triangle", mesh_ale="none", seed_spectrum="mesh"),
    "explicit_paper": dict(scheme="explicit", tension_space="triangle", mesh_ale="none", coupling="kernel",
                           kernel="peskin4", seed_spectrum="mesh"),
}


@pytest.fixture
def device_cupy(monkeypatch):
    """The strict stand-in, or real CuPy with VESICLE_TEST_REAL_CUPY=1 (then a GPU must be there)."""
    if REAL:
        import cupy

        return cupy
    from strict_cupy import install

    return install(monkeypatch)


def mesh():
    return M.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))


def config(case, backend, **extra):
    from vesicle_core.model.run_config import RunConfig

    params = dict(DEFAULT_JOB, dtype="float64", noise_scheme="lm")
    params.update(CASES[case])
    params.update(extra)
    return RunConfig(**params, backend=backend, fft_workers=1)


def run_case(path, cfg, m=None, stop_after_steps=None):
    from vesicle_core.solver.simulate import run

    out = run(m or mesh(), cfg, path, progress=False, stop_after_steps=stop_after_steps)
    if out is None:
        return None
    with xr.open_dataset(out) as ds:
        return ds.load()


def assert_same_run(a, b, atol=ATOL, tension_rtol=1e-6):
    """Same frames, positions within atol, the same step count and the same per-triangle tension to tension_rtol of
    its largest value (the tension answers the positions)."""
    assert b.attrs["backend"] != "numpy" and a.attrs["backend"] == "numpy"
    assert a.sizes["time"] == b.sizes["time"] >= 3
    assert int(a.attrs["steps"]) == int(b.attrs["steps"])
    for v in ("node_x", "node_y", "node_z"):
        np.testing.assert_allclose(b[v].values, a[v].values, rtol=0, atol=atol, err_msg=v)
    scale = float(np.abs(a["tension"].values).max()) * tension_rtol
    np.testing.assert_allclose(b["tension"].values, a["tension"].values, rtol=0, atol=scale + 1e-9)


@pytest.mark.parametrize("case", list(CASES))
def test_strict_discretisation_matches_numpy(device_cupy, monkeypatch, tmp_path, case):
    from vesicle_core.solver import integrators

    # the Arnoldi re-measurement of the bending limit (every 20 steps in runs) every 2 steps, so that these few steps
    # take it on the device too, from the last measurement's vector
    monkeypatch.setattr(integrators, "BENDING_REFRESH", 2)
    cfg_np, cfg_cp = config(case, "numpy"), config(case, "cupy")
    a = run_case(tmp_path / "numpy", cfg_np)
    b = run_case(tmp_path / "cupy", cfg_cp)
    if cfg_np.dtype == "float64":
        assert_same_run(a, b)
    else:
        assert_same_run(a, b, atol=ATOL_FLOAT32, tension_rtol=1e-4)
    if cfg_np.scheme == "inextensible":
        assert int(b.attrs["bending_solves"]) > 0  # the re-measurement ran on the device
    if case.startswith("noise"):
        assert int(b.attrs["thermal_noise_fields"]) > 0 and int(b.attrs["thermal_stokes_solves"]) > 0
    if case.startswith("default"):
        assert int(b.attrs["seed_l_max"]) >= 3  # the thermal seed was put on at the reversal


def test_strict_resume_from_checkpoint_matches_numpy(device_cupy, monkeypatch, tmp_path):
    """A device run stopped after 3 steps (as if interrupted: checkpoint written) and resumed ends where an
    uninterrupted NumPy run ends; the checkpoint carries the bending limit's Arnoldi vector (re-measured every 2
    steps here), the secant preconditioner's model and the lipid area the quality ALE's triangles carry."""
    from vesicle_core.solver import integrators

    monkeypatch.setattr(integrators, "BENDING_REFRESH", 2)
    a = run_case(tmp_path / "numpy", config("noise_lm_secant", "numpy"))
    cfg = config("noise_lm_secant", "cupy", checkpoint_every=1)
    assert cfg.mesh_ale == "quality"
    assert run_case(tmp_path / "cupy", cfg, stop_after_steps=3) is None
    assert (tmp_path / "cupy" / "checkpoint.nc").exists()
    b = run_case(tmp_path / "cupy", cfg)
    assert int(b.attrs["resumed"]) == 1
    assert_same_run(a, b)


def test_strict_decompose_of_device_results_matches_numpy(device_cupy, tmp_path):
    """``vesicle decompose`` of a device run's trajectory gives the NumPy run's spectra."""
    runs = {}
    for name in ("numpy", "cupy"):
        # round-off only (module docstring)
        runs[name] = run_case(tmp_path / name, config("default_job_without_ale", name))
        r = subprocess.run([sys.executable, "-m", "vesicle_core.cli", "decompose",
                            str(tmp_path / name / "trajectory.nc"), "-o", str(tmp_path / f"{name}.nc"), "--quiet",
                            "--l-max", "8"],
                           capture_output=True, text=True, env={**os.environ, "PYTHONPATH": ROOT})
        assert r.returncode == 0, r.stderr
    assert_same_run(runs["numpy"], runs["cupy"])
    with xr.open_dataset(tmp_path / "numpy.nc") as a, xr.open_dataset(tmp_path / "cupy.nc") as b:
        assert set(a.data_vars) == set(b.data_vars)
        # what does not depend on how the shape is turned, to 1e-5 of its largest value (measured: 1.1e-6 in
        # Delta_l at l = 2, which the fitted ellipsoid enters; l_* and t_* exactly). The per-(l, m) coefficients and
        # the fitted ellipsoid's axes and rotation are left out: the 1:0.8:1 start has two equal axes, so the fitted
        # frame turns freely in their plane, and positions equal to 2e-16 R turned it by 4e-4 rad (the per-m
        # coefficients by 1e-4 of the largest)
        for v in ("Delta_tilde_l", "sigma", "A_p_bar", "l_star_t", "t_star", "l_star", "l_peak", "R_eq", "Delta_mesh",
                  "centroid"):
            scale = float(np.nanmax(np.abs(a[v].values), initial=0.0))
            np.testing.assert_allclose(b[v].values, a[v].values, rtol=0, atol=1e-5 * scale + 1e-15, err_msg=v)
        assert float(b.l_star) == pytest.approx(float(a.l_star), rel=1e-12)
