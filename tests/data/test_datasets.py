"""Datasets: CF attributes, atomic writing, validated reading, and the spectra of a synthetic trajectory."""

import math
import os
from datetime import datetime

import numpy as np
import pytest
import xarray as xr
from scipy.special import sph_harm_y

from vesicle_core import __version__
from vesicle_core.analysis import harmonics as H
from vesicle_core.analysis.spectra import spectra_from_trajectory
from vesicle_core.data import datasets as D
from vesicle_core.errors import ConfigError
from vesicle_core.geometry import mesh as M
from vesicle_core.geometry import surface as Sf

# Synthetic run on a level-4 icosphere: an l = 2 "stretch" that decays to its minimum at t = 0.2 (smaller
# still before the reversal, which t_* must ignore) while two axisymmetric wrinkle modes l = 6 and l = 9 grow.
TIMES = np.array([-0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.4])
A2 = np.array([0.001, 0.06, 0.08, 0.05, 0.01, 0.03, 0.06])
A6 = np.array([0.0, 0.0, 0.001, 0.004, 0.008, 0.006, 0.003])
A9 = np.array([0.0, 0.0, 0.0005, 0.003, 0.006, 0.004, 0.002])


def make_trajectory(level=4, times=TIMES, complete=1):
    u, f = M.icosphere(level)
    th, ph = np.arccos(np.clip(u[:, 2], -1, 1)), np.arctan2(u[:, 1], u[:, 0])
    y22 = sph_harm_y(2, 2, th, ph).real
    y60 = sph_harm_y(6, 0, th, ph).real
    y90 = sph_harm_y(9, 0, th, ph).real
    nodes, areas, vols = [], [], []
    for k in range(len(times)):
        v = u * (1 + A2[k] * y22 + A6[k] * y60 + A9[k] * y90)[:, None]
        nodes.append(v)
        areas.append(Sf.surface_area(v, f))
        vols.append(Sf.enclosed_volume(v, f))
    nodes = np.array(nodes)
    nt = len(times)
    rng = np.random.default_rng(0)
    ft = 0.5 + 0.1 * rng.standard_normal((nt, len(f)))
    ds = xr.Dataset(
        {
            "node_x": (("time", "n_node"), nodes[:, :, 0], {"units": "R"}),
            "node_y": (("time", "n_node"), nodes[:, :, 1], {"units": "R"}),
            "node_z": (("time", "n_node"), nodes[:, :, 2], {"units": "R"}),
            "face_node_connectivity": (("n_face", "n_vertex_per_face"), f.astype(np.int32), {"start_index": 0}),
            "face_tension": (("time", "n_face"), ft, {"units": "kappa R-2"}),
            "tension": (("time",), np.linspace(1.0, -2.0, nt), {"units": "kappa R-2"}),
            "area": (("time",), np.array(areas)),
            "volume": (("time",), np.array(vols)),
            "bending_energy": (("time",), np.zeros(nt)),
            "tension_energy": (("time",), np.zeros(nt)),
            "area_drift": (("time",), np.array(areas) / areas[0] - 1),
            "volume_drift": (("time",), np.array(vols) / vols[0] - 1),
        },
        coords={
            "time": ("time", times, {"units": "1", "long_name": "gamma_dot (t - t_reverse)"}),
            "t_tau": ("time", times / 67.0, {"units": "tau"}),
        },
        attrs={"chi": 67.0, "S": 553.0, "delta": 0.02, "Re": 0.01, "N": 64, "mesh_family": "icosphere",
               "mesh_level": level, "backend": "numpy", "complete": complete, "history": "made by a test"},
    )
    return ds


@pytest.fixture(scope="module")
def traj():
    return make_trajectory()


@pytest.fixture(scope="module")
def spectra(traj):
    return spectra_from_trajectory(traj, command="pytest")


def expected_l_star(k):
    """Eq. (31) on the injected modes: axisymmetric modes have sum_m |c_lm|^2 = amplitude^2."""
    c6, c9 = A6[k] ** 2, A9[k] ** 2
    return math.sqrt((36 * c6 + 81 * c9) / (c6 + c9))


# --------------------------------------------------------------------------- spectra
def test_spectra_layout(spectra, traj):
    ds = spectra
    L = int(ds.attrs["l_max"])
    assert L == 41  # level 4 resolves pi / (mean edge 0.0757) = 41 < 64
    assert ds.sizes == {"time": 7, "l": L + 1, "m": 2 * L + 1, "axis": 3, "principal": 3}
    for v in D.SPECTRA_VARIABLES:
        assert v in ds, v
    for name, var in ds.data_vars.items():
        assert "units" in var.attrs and "long_name" in var.attrs, name
    assert ds["u_real"].dims == ("time", "l", "m") and ds["Delta_l"].dims == ("time", "l")
    assert ds["ellipsoid_axes"].dims == ("time", "axis")
    # NaN exactly where |m| > l
    bad = np.abs(ds["m"].values)[None, :] > ds["l"].values[:, None]
    u0 = ds["u_real"].isel(time=3).values
    assert np.all(np.isnan(u0[bad])) and np.all(np.isfinite(u0[~bad]))
    np.testing.assert_array_equal(ds["sigma"].values, traj["tension"].values)
    np.testing.assert_array_equal(ds["t_tau"].values, traj["t_tau"].values)
    a = Sf.triangle_areas(np.stack([traj[c].isel(time=1).values for c in ("node_x", "node_y", "node_z")], 1),
                         traj["face_node_connectivity"].values)
    ft = traj["face_tension"].isel(time=1).values
    assert float(ds["face_tension_mean"][1]) == pytest.approx((ft * a).sum() / a.sum())
    # trajectory attrs carried over, CF attrs on top
    assert ds.attrs["chi"] == 67.0 and ds.attrs["S"] == 553.0 and ds.attrs["complete"] == 1
    assert ds.attrs["Conventions"] == "CF-1.10" and __version__ in ds.attrs["source"]
    assert "pytest" in ds.attrs["history"] and ds.attrs["history"].endswith("made by a test")
    assert ds.attrs["delta_used"] == 0.02 and ds.attrs["rule"] == "pn"


def test_spectra_values_t_star_l_star(spectra):
    ds = spectra
    D2 = ds["Delta_l"].sel(l=2).values
    # Delta_2 = (A2^2 / 2) * 4 / delta for Re Y22: check the scaling of eq. (30)
    assert D2[3] == pytest.approx(0.5 * A2[3] ** 2 * 4 / 0.02, rel=0.01)
    assert float(ds["t_star"]) == pytest.approx(0.2)  # not -0.2, where Delta_2 is smaller still
    k = 4
    assert float(ds["l_star"]) == pytest.approx(expected_l_star(k), rel=0.01)
    assert float(ds["l_star"]) == float(ds["l_star_t"][k])
    assert int(ds["l_max_nontrivial"]) == int(ds["l_max_nontrivial_t"][k]) >= 9
    for j in (3, 5, 6):
        assert float(ds["l_star_t"][j]) == pytest.approx(expected_l_star(j), rel=0.02)
    # the injected wrinkle modes dominate Delta~_l at t_*; A_p-bar follows the wrinkle amplitude
    Dt = ds["Delta_tilde_l"].isel(time=k).values
    assert set(np.argsort(Dt)[-2:]) == {6, 9}
    Apb = ds["A_p_bar"].values
    assert int(np.argmax(Apb)) == k and Apb[0] < 1e-3 * Apb[k]
    # u_lm of the injected axisymmetric l = 6 mode (m = 0), unscaled by sqrt((l-1)(l+2)/Delta)
    u60 = float(ds["u_real"].sel(l=6, m=0)[k]) / math.sqrt(5 * 8 / 0.02)
    assert u60 == pytest.approx(A6[k], rel=0.01)


def test_spectra_stride_lmax_and_maps(traj):
    ds = spectra_from_trajectory(traj, l_max=12, stride=2, map_shape=(8, 16))
    assert ds.sizes["time"] == 4 and ds.sizes["l"] == 13
    np.testing.assert_array_equal(ds["time"].values, TIMES[::2])
    assert ds["A_p_map"].dims == ("time", "theta", "phi") and ds["A_p_map"].shape == (4, 8, 16)
    assert np.all(np.isfinite(ds["A_p_map"].values))
    with pytest.warns(H.ResolutionWarning):
        spectra_from_trajectory(traj.isel(time=[0]), l_max=60)


def test_t_star_undefined_without_reversal(traj):
    ds = spectra_from_trajectory(traj.isel(time=[0, 1]), l_max=8)
    assert np.isnan(float(ds["t_star"])) and np.isnan(float(ds["l_star"]))
    assert int(ds["l_max_nontrivial"]) == -1


# --------------------------------------------------------------------------- writing and reading
def as_written(ds):
    """``ds`` with what writing adds: CF units (solver units as "1" + nondimensional_units) and the scales."""
    from vesicle_core.model.units import SCALE_ATTRS, cf_unit_attrs

    out = ds.copy()
    for var in out.variables.values():
        var.attrs = cf_unit_attrs(var.attrs)
    out.attrs = {**ds.attrs, **{k: v for k, v in SCALE_ATTRS.items() if k not in ds.attrs}}
    return out


def test_roundtrip_identical(spectra, tmp_path):
    p = tmp_path / "spectra.nc"
    D.write_dataset(spectra, p)
    back = D.read_dataset(p, "spectra")
    xr.testing.assert_identical(back, as_written(spectra))  # the values bit for bit, only metadata added
    assert back["sigma"].attrs["units"] == "1" and back["sigma"].attrs["nondimensional_units"] == "kappa/R^2"
    # large variables are compressed, small ones are not
    with xr.open_dataset(p) as raw:
        assert raw["u_real"].encoding.get("zlib") is True and raw["u_real"].encoding.get("complevel") == 4
        assert not raw["sigma"].encoding.get("zlib", False)


def test_roundtrip_trajectory(traj, tmp_path):
    p = tmp_path / "trajectory.nc"
    D.write_dataset(traj, p)
    with D.open_trajectory(p) as back:
        xr.testing.assert_identical(back.load(), as_written(traj))


def test_interrupted_write_leaves_nothing(spectra, tmp_path, monkeypatch):
    p = tmp_path / "spectra.nc"
    D.write_dataset(spectra.isel(time=[0]), p)
    before = p.read_bytes()
    original = xr.Dataset.to_netcdf

    def broken(self, path, *args, **kwargs):
        original(self, path, *args, **kwargs)  # the temp file is fully written ...
        with open(path, "r+b") as fh:  # ... then truncated, as by a crash midway
            fh.truncate(100)
        raise KeyboardInterrupt("killed while writing")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", broken)
    with pytest.raises(KeyboardInterrupt):
        D.write_dataset(spectra, p)
    assert p.read_bytes() == before  # the previous file is untouched
    q = tmp_path / "new.nc"
    with pytest.raises(KeyboardInterrupt):
        D.write_dataset(spectra, q)
    assert not q.exists()
    assert sorted(os.listdir(tmp_path)) == ["spectra.nc"]  # no temp file left behind


def test_read_errors_name_the_file(spectra, tmp_path):
    missing = tmp_path / "nope.nc"
    with pytest.raises(D.MissingDataError, match="nope.nc: file does not exist"):
        D.read_dataset(missing, "spectra")
    junk = tmp_path / "junk.nc"
    junk.write_text("not netCDF at all")
    with pytest.raises(D.DatasetError, match="junk.nc: not a readable netCDF file"):
        D.read_dataset(junk, "spectra")
    partial = tmp_path / "partial.nc"
    D.write_dataset(spectra[["Delta_l", "sigma"]], partial)
    with pytest.raises(D.MissingDataError, match=r"partial.nc: not a spectra dataset: missing variable\(s\) u_real"):
        D.read_dataset(partial, "spectra")
    with pytest.raises(D.MissingDataError, match="missing"):
        D.open_trajectory(partial)
    assert D.read_dataset(partial, required=["sigma"])["sigma"].size == 7
    with pytest.raises(ConfigError, match="unknown dataset kind"):
        D.read_dataset(partial, "nonsense")


def test_open_trajectory_validation(tmp_path):
    ok = tmp_path / "t.nc"
    D.write_dataset(make_trajectory(level=2, times=TIMES[:3]), ok)
    with D.open_trajectory(ok) as ds:
        assert ds.sizes["n_vertex_per_face"] == 3
    inc = tmp_path / "incomplete.nc"
    D.write_dataset(make_trajectory(level=2, times=TIMES[:3], complete=0), inc)
    with pytest.warns(D.IncompleteRunWarning, match="did not finish"):
        D.open_trajectory(inc).close()
    with pytest.raises(D.DatasetError, match="incomplete.nc: the run did not finish"):
        D.open_trajectory(inc, require_complete=True)
    bad = make_trajectory(level=2, times=TIMES[:3])
    bad["face_node_connectivity"][0, 0] = 10_000
    with pytest.raises(D.DatasetError, match="indices must lie"):
        D.validate_trajectory(bad)
    with pytest.raises(D.DatasetError, match="dims"):
        D.validate_trajectory(bad.assign(tension=(("n_face",), np.zeros(bad.sizes["n_face"]))))
    with pytest.raises(D.DatasetError, match="strictly increasing"):
        D.validate_trajectory(make_trajectory(level=2, times=np.array([0.0, 0.0, 0.1])))


def test_cf_attrs_netcdf_safe(tmp_path):
    a = D.cf_attrs("a title", command="vesicle decompose x.nc", flag=True, nothing=None, level=np.int64(5),
                   axes=(1.0, 0.8, 1.0), mesh={"family": "icosphere", "seed": 3}, path=tmp_path, names=["a", "b"])
    assert a["Conventions"] == "CF-1.10" and a["title"] == "a title"
    assert a["source"] == f"vesicle_core {__version__}"
    stamp, cmd = a["history"].split(" ", 1)
    assert datetime.fromisoformat(stamp).tzinfo is not None and cmd == "vesicle decompose x.nc"
    assert a["flag"] == 1 and a["nothing"] == "none" and a["level"] == 5
    assert np.allclose(a["axes"], [1.0, 0.8, 1.0])
    assert a["mesh_family"] == "icosphere" and a["mesh_seed"] == 3
    assert a["path"] == str(tmp_path) and a["names"] == '["a", "b"]'
    p = tmp_path / "x.nc"
    ds = xr.Dataset({"x": ("i", np.arange(3.0))}, attrs=a)
    D.write_dataset(ds, p)
    back = D.read_dataset(p)
    assert back.attrs["mesh_family"] == "icosphere" and back.attrs["flag"] == 1
    with pytest.raises(ConfigError, match="collides"):
        D.cf_attrs("t", Conventions="x")
