"""The thermal wrinkle seed (seeding.py) and the stored membrane velocity, checked against their definitions:
the seeded shape's spherical-harmonic spectrum is the PA's initial draw, and the stored velocity is the step
the trajectory actually took."""

import numpy as np
import pytest
import xarray as xr
from unit_run import unit_run

from vesicle_core.analysis import harmonics as H
from vesicle_core.errors import ConfigError
from vesicle_core.geometry import mesh as M
from vesicle_core.model.modes import initial_state
from vesicle_core.solver.seeding import thermal_coefficients, thermal_seed
from vesicle_core.solver.simulate import run

DELTA, S = 0.116, 553.0


@pytest.fixture(scope="module")
def sphere():
    return M.make_vesicle("icosphere", level=5, axes=(1.0, 1.0, 1.0))


def test_seeded_sphere_carries_the_pa_initial_spectrum(sphere):
    # scale 1e4 lifts the seed far above the mesh's own roughness; the spectrum is linear in the amplitude
    X, l_max = thermal_seed(sphere.vertices, sphere.faces, delta=DELTA, S=S, seed=3, scale=1e4, l_max=12)
    assert l_max == 12
    u = H.decompose(X, sphere.faces, 12, delta=DELTA)
    u_pa = initial_state(12, S, delta=DELTA, seed=3) * 100.0
    got, want = H.delta_l(u)[3:], H.delta_l(u_pa)[3:]
    np.testing.assert_allclose(got, want, rtol=0.05)
    # the phases too, mode by mode (m >= 0 determines the real field)
    np.testing.assert_allclose(u[3:, 12:], u_pa[3:, 12:], atol=0.05 * np.abs(u_pa[3:]).max())
    assert H.delta_l(u)[2] < 1e-3 * want[0]  # l = 2 is left to the flow


def test_scale_multiplies_the_variance():
    c1 = thermal_coefficients(DELTA, S, l_max=20, seed=1)
    c10 = thermal_coefficients(DELTA, S, l_max=20, seed=1, scale=10.0)
    np.testing.assert_allclose(np.abs(c10) ** 2, 10.0 * np.abs(c1) ** 2, rtol=1e-12)
    assert np.all(c1[:3] == 0)


@pytest.mark.parametrize(
    "kw, name",
    [
        (dict(seed_spectrum="white"), "seed_spectrum"),
        (dict(seed_scale=-1), "seed_scale"),
        (dict(seed=-2), "seed"),
        (dict(seed_spectrum="thermal", stationary_tol=0.1), "stationary_tol"),
        (dict(store_velocity="yes"), "store_velocity"),
    ],
)
def test_bad_seed_config_names_field(kw, name):
    with pytest.raises(ConfigError, match=name):
        unit_run(**kw)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("seed")
    m = M.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    base = dict(
        chi=20.0,
        N=16,
        stretch=0.1,
        t_end=0.02,
        output_every=0.005,
        Lambda=2e4,
        K_volume=1e6,
        dt=2.5e-4,
        store_velocity=True,
    )
    out = {}
    for name, extra in (("mesh", {}), ("thermal", dict(seed_spectrum="thermal", seed_scale=100.0))):
        with xr.open_dataset(run(m, unit_run(**base, **extra), d / name, progress=False)) as ds:
            out[name] = ds.load()
    return out


def _pos(ds):
    return np.stack([ds[c].values for c in ("node_x", "node_y", "node_z")], axis=-1)


def test_seed_changes_the_shape_at_the_reversal_only(pair):
    a, b = pair["mesh"], pair["thermal"]
    before = a["time"].values < -1e-9
    np.testing.assert_array_equal(_pos(a)[before], _pos(b)[before])
    i0 = int(np.argmin(np.abs(a["time"].values)))
    assert np.abs(_pos(a)[i0] - _pos(b)[i0]).max() > 1e-4
    assert int(b.attrs["seed_l_max"]) >= 3


def test_stored_velocity_is_the_step_taken(pair):
    ds = pair["mesh"]
    X, U = _pos(ds), np.stack([ds[c].values for c in ("node_ux", "node_uy", "node_uz")], axis=-1)
    assert np.isfinite(U).all()
    # a frame every step (output_every = chi dt): each frame's velocity times dt is the next frame's displacement
    dX = np.diff(X, axis=0)
    dt = np.diff(ds["t_tau"].values)
    np.testing.assert_allclose(dt, 2.5e-4, rtol=1e-9)
    np.testing.assert_allclose(dX, U[:-1] * dt[:, None, None], rtol=1e-9, atol=1e-14)
