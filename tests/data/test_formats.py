"""The files other tools open: every dataset kind the workflow writes has CF units that UDUNITS parses (cf-units,
the UDUNITS-2 library) and states its scales; cf-xarray finds its CF roles; meshes and trajectories are UGRID 1.0
2D meshes that xugrid opens (docs/reference/datasets.md)."""

import warnings

import numpy as np
import pytest
import xarray as xr

from vesicle_core.cli import main
from vesicle_core.geometry import mesh as M
from vesicle_core.model.run_config import RunConfig
from vesicle_core.model.units import SCALE_ATTRS, SOLVER_UNITS, cf_unit_attrs
from vesicle_core.solver.simulate import run
from vesicle_core.solver.trajectory import _as_ugrid

KINDS = ("mesh", "trajectory", "spectra", "theory", "fit")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """One file of every kind, each written the way the workflow writes it (the ``vesicle`` commands)."""
    d = tmp_path_factory.mktemp("formats")
    out = {"mesh": d / "mesh.nc", "spectra": d / "spectra.nc", "fit": d / "fit.nc"}
    assert main(["mesh", "-o", str(out["mesh"]), "--family", "icosphere", "--level", "2", "--delta", "0.116"]) == 0
    cfg = RunConfig(chi=20.0, N=16, stretch=0.2, t_end=0.1, output_every=0.05, Lambda=2e4, K_volume=1e6,
                    store_velocity=True)
    out["trajectory"] = run(M.load(out["mesh"]), cfg, d / "run", progress=False)
    assert main(["decompose", str(out["trajectory"]), "-o", str(out["spectra"]), "--l-max", "6", "--quiet"]) == 0
    theories = []
    for S in (40, 80, 160):
        theories.append(d / f"theory_S{S}.nc")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # l_max = 12 truncates the PA: a small file is all this test needs
            assert main(["theory", "--delta", "0.116", "--S", str(S), "--l-max", "12", "--n-out", "40",
                         "-o", str(theories[-1])]) == 0
    out["theory"] = theories[0]
    assert main(["fit", str(out["spectra"]), *map(str, theories), "-o", str(out["fit"])]) == 0
    return out


@pytest.mark.parametrize("kind", KINDS)
def test_cf_units_parse_with_udunits_and_state_their_scale(files, kind):
    cf_units = pytest.importorskip("cf_units")
    with xr.open_dataset(files[kind], decode_cf=False) as ds:
        assert ds.attrs["Conventions"].startswith("CF-1."), ds.attrs.get("Conventions")
        for key in SCALE_ATTRS:
            assert key in ds.attrs, f"{kind}: global attribute {key} missing"
        n_units = 0
        for name, var in ds.variables.items():
            u = var.attrs.get("units")
            if u is None:
                continue
            n_units += 1
            unit = cf_units.Unit(u)  # raises for what UDUNITS-2 cannot parse ("kappa", "tau", "kappa/R^2")
            assert not unit.is_unknown(), (kind, name, u)
            # every quantity is a pure number or an angle: "R" parses, but as the roentgen (an exposure)
            assert unit.is_dimensionless(), f"{kind}: {name} has units {u!r}, not a dimensionless CF unit"
            scale = var.attrs.get("nondimensional_units")
            if scale is not None:
                assert u == "1", (kind, name)
                assert scale in SOLVER_UNITS or scale.removeprefix("same as ") in ds.variables, (kind, name, scale)
            if var.attrs.get("standard_name") in ("longitude", "latitude"):
                assert unit.is_convertible(cf_units.Unit("degree")), (kind, name, u)
        assert n_units > 0
    if kind in ("trajectory", "spectra", "theory"):  # the tension is a number in kappa/R^2
        with xr.open_dataset(files[kind]) as ds:
            sigma = ds["tension" if kind == "trajectory" else "sigma"]
            assert sigma.attrs["units"] == "1" and sigma.attrs["nondimensional_units"] == "kappa/R^2"


@pytest.mark.parametrize("kind", ("mesh", "trajectory"))
def test_cf_xarray_finds_the_ugrid_roles(files, kind):
    pytest.importorskip("cf_xarray")
    with xr.open_dataset(files[kind]) as ds:
        roles = ds.cf.cf_roles
        assert roles["mesh_topology"] == ["mesh"] and roles["face_node_connectivity"] == ["face_node_connectivity"]
        assert ds.cf["longitude"].name == "node_lon" and ds.cf["latitude"].name == "node_lat"
        assert ds.attrs["Conventions"] == "CF-1.10 UGRID-1.0"
        topo = ds["mesh"].attrs
        assert topo["topology_dimension"] == 2 and topo["node_coordinates"] == "node_lon node_lat"
        assert topo["face_dimension"] == "n_face" and ds["face_node_connectivity"].attrs["start_index"] == 0


def test_xugrid_opens_a_trajectory_and_reads_the_face_tension(files):
    xu = pytest.importorskip("xugrid")
    with xr.open_dataset(files["trajectory"]) as raw:
        raw = raw.load()
    uds = xu.UgridDataset(raw)
    grid = uds.ugrid.grid
    assert grid.n_face == raw.sizes["n_face"] and grid.n_node == raw.sizes["n_node"]
    np.testing.assert_array_equal(grid.face_node_connectivity, raw["face_node_connectivity"].values)
    ft = uds["face_tension"]
    assert isinstance(ft, xu.UgridDataArray) and ft.dims == ("time", "n_face")
    np.testing.assert_array_equal(ft.values, raw["face_tension"].values)
    # a field on the mesh: the area-weighted face tension of the last frame, with the areas of that frame
    X = np.stack([raw[f"node_{c}"].values[-1] for c in "xyz"], axis=1)
    f = grid.face_node_connectivity
    areas = 0.5 * np.linalg.norm(np.cross(X[f[:, 1]] - X[f[:, 0]], X[f[:, 2]] - X[f[:, 0]]), axis=1)
    mean = float((ft.isel(time=-1).values * areas).sum() / areas.sum())
    assert np.isfinite(mean) and abs(mean) > 0
    # node coordinates: the vertex directions of the first frame (every vertex on the sphere of directions)
    lon, lat = M.node_lonlat(np.stack([raw[f"node_{c}"].values[0] for c in "xyz"], axis=1))
    np.testing.assert_allclose(grid.node_x, lon)
    np.testing.assert_allclose(grid.node_y, lat)


def test_xugrid_opens_a_mesh(files):
    xu = pytest.importorskip("xugrid")
    with xr.open_dataset(files["mesh"]) as raw:
        uds = xu.UgridDataset(raw.load())
    m = M.load(files["mesh"])
    assert uds.ugrid.grid.n_face == len(m.faces)
    np.testing.assert_array_equal(uds.ugrid.grid.face_node_connectivity, m.faces)


def test_ugrid_conversion_changes_no_stored_value(files):
    """Only attributes and the new UGRID variables: every variable of the written trajectory holds what it held."""
    with xr.open_dataset(files["trajectory"]) as ds:
        ds = ds.load()
    old = ds.drop_vars(["mesh", "node_lon", "node_lat"])
    for var in old.variables.values():  # the units as the solver wrote them before the CF conversion
        if var.attrs.get("nondimensional_units"):
            var.attrs["units"] = var.attrs.pop("nondimensional_units")
    new = _as_ugrid(old.copy(deep=True))
    for name in old.variables:
        assert new[name].dtype == old[name].dtype
        np.testing.assert_array_equal(new[name].values, old[name].values, err_msg=name)
    assert new["face_tension"].attrs["units"] == "1"


def test_cf_unit_attrs_is_idempotent_and_leaves_cf_units_alone():
    once = cf_unit_attrs({"units": "kappa/R^2", "long_name": "tension"})
    assert once == {"units": "1", "nondimensional_units": "kappa/R^2", "long_name": "tension"}
    assert cf_unit_attrs(once) == once
    assert cf_unit_attrs({"units": "rad"}) == {"units": "rad"}
    assert cf_unit_attrs({"units": "same as sigma"})["nondimensional_units"] == "same as sigma"
    assert cf_unit_attrs({"units": "kappa R-2"}) == {"units": "1", "nondimensional_units": "kappa/R^2"}


def test_the_per_frame_scalars_are_those_docs_datasets_lists(files):
    """docs/reference/datasets.md's table of per-frame scalars names exactly what a trajectory stores along time
    (one home:
    TrajectoryWriter.FRAME_VARS, checked against the doc and a written file)."""
    import re
    from pathlib import Path

    from vesicle_core.solver.trajectory import TrajectoryWriter

    doc = (Path(__file__).resolve().parents[2] / "docs" / "reference" / "datasets.md").read_text()
    section = doc.split("### Per-frame scalars of a trajectory")[1].split("\n#")[0]
    listed = {name for row in section.splitlines() if row.startswith("| `")
              for name in re.findall(r"`([a-z_0-9]+)`", row.split("|")[1])}
    assert listed == set(TrajectoryWriter.FRAME_VARS)
    with xr.open_dataset(files["trajectory"]) as ds:
        along_time = {k for k, v in ds.variables.items() if v.dims == ("time",)}
    assert set(TrajectoryWriter.FRAME_VARS) <= along_time
    q = xr.open_dataset(files["trajectory"]).mesh_quality_min.values
    assert np.all((q > 0) & (q <= 1))
