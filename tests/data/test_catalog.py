"""Catalog: catalog.csv + ESM JSON, open_sweep on synthetic spectra/theory files (layouts of datasets.py and
theory.py, built here so the catalog is tested on its own)."""

import argparse
import ast
import csv
import json
import math

import numpy as np
import pytest
import xarray as xr
from unit_run import unit_run

from vesicle_core.data import case_ids as Ci
from vesicle_core.data import catalog as C
from vesicle_core.data import sweep as Sw
from vesicle_core.model.units import chi_from_S


# --------------------------------------------------------------------------- synthetic datasets
def synthetic_spectra(delta, S, n_time=21, t0=-0.4, t1=1.0, l_max=12, kind="spectra", N=32, level=3, seed=0,
                      run_attrs=None):
    """A small dataset with the layout of spectra.nc (kind="spectra") or theory.nc (kind="theory"). Without
    ``run_attrs`` the attributes are those of an old file (no n_vertices, scheme, dtype or kernel)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(t0, t1, n_time)
    l = np.arange(l_max + 1)
    m = np.arange(-l_max, l_max + 1)
    invalid = np.abs(m)[None, :] > l[:, None]
    ur = rng.normal(size=(n_time, l.size, m.size)) * 1e-2
    ui = rng.normal(size=(n_time, l.size, m.size)) * 1e-2
    ur[:, invalid] = np.nan
    ui[:, invalid] = np.nan
    D = np.nansum(ur**2 + ui**2, axis=2)
    lstar = 3.0 + S ** (1.0 / 3.0) / 2.0
    data = {
        "u_real": (("time", "l", "m"), ur),
        "u_imag": (("time", "l", "m"), ui),
        "Delta_l": (("time", "l"), D),
        "sigma": (("time",), np.where(t < 0, 50.0, -20.0 * (1 + t) ** -0.8)),
        "l_star_t": (("time",), np.full(n_time, lstar)),
        "t_star": ((), 0.25),
        "l_star": ((), lstar),
        "l_peak": ((), round(lstar)),
        "l_max_nontrivial": ((), np.int32(l_max)),
    }
    if kind == "spectra":
        data.update({
            "A_p_bar": (("time",), np.linspace(0, 1e-3, n_time)),
            "Delta_tilde_l": (("time", "l"), D * 0.5),
            "face_tension_mean": (("time",), np.zeros(n_time)),
            "face_tension_std": (("time",), np.ones(n_time)),
            "A_p_map": (("time", "theta", "phi"), rng.normal(size=(n_time, 4, 8))),
        })
    coords = {"time": t, "l": l, "m": m}
    if kind == "spectra":
        coords.update(theta=np.linspace(0.2, 3.0, 4), phi=np.linspace(-3.0, 3.0, 8))
    attrs = {"delta": delta + 1e-13, "S": S * (1 + 1e-9), "chi": chi_from_S(S, delta),
             "source": "vesicle_core 9.9.9", "history": "2026-01-02T03:04:05+00:00 vesicle decompose x"}
    if kind == "spectra":
        attrs.update(N=N, mesh_level=level, mesh_family="icosphere", backend="numpy", mesh_delta=delta + 1e-13,
                     mesh_target_delta=delta)
        attrs.update(run_attrs or {})
    return xr.Dataset(data, coords=coords, attrs=attrs)


def write_sweep(root, points, *, N=32, level=3, theory=True, family="icosphere", n_vertices=None, tag=None,
                run_attrs=None, kT=0.0, noise_seed=0):
    """Write results/runs/<id>/spectra.nc (+ theory/<id>.nc, a mesh and a fit-like file) under ``root``;
    returns the written paths."""
    paths = []
    for i, (delta, S, n_time) in enumerate(points):
        cid = Ci.case_id(delta, S=S, N=N, family=family, level=level, n_vertices=n_vertices, tag=tag, kT=kT,
                         noise_seed=noise_seed)
        p = root / "runs" / cid / "spectra.nc"
        p.parent.mkdir(parents=True, exist_ok=True)
        extra = dict(run_attrs or {})
        if family != "icosphere":
            extra.update(mesh_family=family, mesh_level=-1)
        if kT > 0:
            extra.update(kT=kT, noise_seed=noise_seed)
        synthetic_spectra(delta, S, n_time=n_time, N=N, level=level, seed=i + 100 * noise_seed,
                          run_attrs=extra).to_netcdf(p)
        paths.append(p)
        if theory:
            tp = root / "theory" / f"{Ci.theory_id(delta, S)}.nc"
            tp.parent.mkdir(parents=True, exist_ok=True)
            synthetic_spectra(delta, S, n_time=51, t0=0.0, t1=1.5, l_max=20, kind="theory").to_netcdf(tp)
            paths.append(tp)
    mp = root / "meshes" / f"{Ci.mesh_id(points[0][0], family, level=level, n_vertices=n_vertices)}.nc"
    mp.parent.mkdir(parents=True, exist_ok=True)
    xr.Dataset(
        {"node_x": ("n_node", np.zeros(4)), "node_y": ("n_node", np.zeros(4)), "node_z": ("n_node", np.zeros(4)),
         "face_node_connectivity": (("n_face", "n_vertex_per_face"), np.zeros((4, 3), dtype="i4"))},
        attrs={"family": "icosphere", "level": level, "delta": points[0][0], "target_delta": points[0][0],
               "source": "vesicle_core 9.9.9"},
    ).to_netcdf(mp)
    paths.append(mp)
    fp = root / "fits" / "lstar_vs_S.nc"
    fp.parent.mkdir(parents=True, exist_ok=True)
    xr.Dataset({"l_star_exponent": ("group", [0.39])}).to_netcdf(fp)
    paths.append(fp)
    return paths


# --------------------------------------------------------------------------- catalog files
def test_write_catalog_rows_and_esm_json(tmp_path):
    root = tmp_path / "results"
    paths = write_sweep(root, [(0.116, 553.0, 21), (0.116, 1106.5, 31)])
    rows = C.write_catalog(paths, root / "catalog.csv")
    assert len(rows) == len(paths)
    with open(root / "catalog.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert list(table[0]) == list(C.COLUMNS)
    kinds = sorted(r["kind"] for r in table)
    assert kinds == ["fit", "mesh", "spectra", "spectra", "theory", "theory"]
    spec = [r for r in table if r["kind"] == "spectra"]
    assert {float(r["S"]) for r in spec} == {553.0, 1106.5}  # nominal values from the ids, not the 1e-9 noise
    r = next(r for r in spec if r["case_id"] == "D0.116_S553_N32_L3")
    assert float(r["Delta"]) == 0.116 and int(r["N"]) == 32 and int(r["mesh_level"]) == 3
    assert r["backend"] == "numpy" and r["package_version"] == "9.9.9"
    assert r["created"].startswith("2026-01-02T03:04:05")
    assert r["path"] == "runs/D0.116_S553_N32_L3/spectra.nc"  # relative to the catalog
    assert float(r["chi"]) == pytest.approx(chi_from_S(553.0, 0.116))
    mesh = next(r for r in table if r["kind"] == "mesh")
    assert mesh["mesh_family"] == "icosphere" and mesh["S"] == ""
    esm = json.loads((root / "catalog.json").read_text())
    for key in ("esmcat_version", "id", "description", "attributes", "assets", "catalog_file"):
        assert key in esm
    assert esm["assets"] == {"column_name": "path", "format": "netcdf"}
    assert esm["catalog_file"] == ("catalog.parquet" if C.have_pyarrow() else "catalog.csv")
    assert {a["column_name"] for a in esm["attributes"]} >= {"kind", "case_id", "Delta", "S", "chi", "N"}
    # every row points at a file that opens, also through the JSON
    for row in C.read_catalog(root / "catalog.json"):
        with xr.open_dataset(row["abspath"]):
            pass


def test_catalog_errors_name_the_file(tmp_path):
    bad = tmp_path / "x.nc"
    bad.write_text("not netcdf")
    with pytest.raises(C.CatalogError, match="x.nc"):
        C.catalog_row(bad)
    with pytest.raises(C.CatalogError, match="does not exist"):
        C.catalog_row(tmp_path / "missing.nc")


# --------------------------------------------------------------------------- open_sweep
def test_open_sweep_stacks_spectra_along_delta_and_S(tmp_path):
    root = tmp_path / "results"
    pts = [(0.116, 553.0, 21), (0.116, 1106.5, 31), (0.116, 2224.0, 15), (0.997, 237.0, 25)]
    C.write_catalog(write_sweep(root, pts), root / "catalog.csv")
    ds = Sw.open_sweep(root / "catalog.csv")
    assert ds.sizes["Delta"] == 2 and ds.sizes["S"] == 4
    lstar = float(ds.l_star.sel(S=553).sel(Delta=0.116))
    assert lstar == pytest.approx(3.0 + 553.0 ** (1 / 3) / 2)
    assert math.isnan(float(ds.l_star.sel(S=553, Delta=0.997)))  # not in the sweep: NaN
    assert ds.l_star.sel(S=553).dims == ("Delta",)
    # time series on one common grid, inside every run's range
    assert "sigma" in ds and ds.sigma.dims == ("Delta", "S", "time")
    assert ds.time.min() >= -0.4 and ds.time.max() <= 1.0 and ds.sizes["time"] >= 2
    assert np.isfinite(ds.sigma.sel(Delta=0.116, S=2224.0)).all()
    # per-l at t_*, no m arrays, metadata per point
    assert "Delta_l_at_t_star" in ds and "u_real" not in ds and "A_p_map" not in ds
    assert str(ds.case_id.sel(Delta=0.116, S=1106.5).values) == "D0.116_S1106.5_N32_L3"
    assert float(ds.chi.sel(Delta=0.116, S=553)) == pytest.approx(chi_from_S(553.0, 0.116))
    # the JSON and the directory work too; theory stacks the same way
    assert Sw.open_sweep(root / "catalog.json").sizes["S"] == 4
    th = Sw.open_sweep(root, kind="theory")
    assert th.sizes["S"] == 4 and "Delta_tilde_l_at_t_star" not in th
    # explicit common time grid
    grid = np.linspace(0.0, 0.5, 6)
    assert Sw.open_sweep(root / "catalog.csv", time=grid).sizes["time"] == 6


def test_open_sweep_filters_and_duplicates(tmp_path):
    root = tmp_path / "results"
    paths = write_sweep(root, [(0.116, 553.0, 21)], N=32, theory=False)
    paths += [p for p in write_sweep(root, [(0.116, 553.0, 11)], N=64, theory=False) if p.name == "spectra.nc"]
    C.write_catalog(sorted(set(paths)), root / "catalog.csv")
    with pytest.raises(C.CatalogError, match="N=..."):
        Sw.open_sweep(root / "catalog.csv")
    ds = Sw.open_sweep(root / "catalog.csv", N=64)
    assert str(ds.case_id.item()) == "D0.116_S553_N64_L3"
    with pytest.raises(C.CatalogError, match="no spectra"):
        Sw.open_sweep(root / "catalog.csv", N=128)
    with pytest.raises(C.CatalogError, match="unknown catalog column"):
        Sw.open_sweep(root / "catalog.csv", colour="red")


def test_open_sweep_stacks_an_ensemble_along_noise_seed(tmp_path):
    """Seeds as a sweep dimension: 3 noise seeds at 2 S give (Delta, S, noise_seed); the catalog carries kT and
    the seed; a deterministic run at the same points is refused in one stack and selected by kT=0."""
    root = tmp_path / "results"
    pts = [(0.116, 553.0, 21), (0.116, 2224.0, 21)]
    paths = []
    for seed in (0, 1, 2):
        paths += [p for p in write_sweep(root, pts, theory=False, kT=0.0405, noise_seed=seed) if p.name == "spectra.nc"]
    det = [p for p in write_sweep(root, pts, theory=False) if p.name == "spectra.nc"]
    C.write_catalog(sorted(set(paths + det)), root / "catalog.csv")
    rows = [r for r in C.read_catalog(root / "catalog.csv") if r["kind"] == "spectra"]
    assert sorted({(float(r["kT"]), r["noise_seed"]) for r in rows}, key=str) == sorted(
        {(0.0, None), (0.0405, 0), (0.0405, 1), (0.0405, 2)}, key=str)
    with pytest.raises(C.CatalogError, match="kT=0"):
        Sw.open_sweep(root / "catalog.csv")
    ens = Sw.open_sweep(root / "catalog.csv", kT=0.0405)
    assert dict(ens.l_star.sizes) == {"Delta": 1, "S": 2, "noise_seed": 3}
    assert list(ens.noise_seed.values) == [0, 1, 2]
    assert str(ens.case_id.sel(S=553, noise_seed=1).item()) == "D0.116_S553_N32_L3_kT0.0405_n1"
    assert float(ens.kT.sel(S=553, noise_seed=2).item()) == 0.0405
    # the distribution over seeds: mean and spread of the time series differ from any one member
    assert ens.sigma.mean("noise_seed").dims == ("Delta", "S", "time")
    one = Sw.open_sweep(root / "catalog.csv", kT=0)
    assert "noise_seed" not in one.dims and one.sizes["S"] == 2


def test_catalog_command(tmp_path, capsys):
    from vesicle_core.cli.post import add_catalog

    root = tmp_path / "results"
    paths = write_sweep(root, [(0.116, 553.0, 21), (0.116, 2224.0, 21)])
    parser = argparse.ArgumentParser(prog="vesicle")
    add_catalog(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["catalog", *map(str, paths), "-o", str(root / "catalog.csv")])
    assert args.func(args) == 0
    assert "6 datasets" in capsys.readouterr().out
    assert (root / "catalog.json").is_file()
    assert Sw.open_sweep(root / "catalog.csv").sizes["S"] == 2


# --------------------------------------------------------------------------- mesh and run columns
NEW_COLUMNS = ("n_vertices", "mesh_family", "scheme", "dtype", "kernel", "coupling", "tension_space", "tag")


def _csv_table(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def real_runs(tmp_path_factory):
    """Two tiny IBM runs at the same nominal (Delta, S) and grid N = 16 that differ in mesh (icosphere L1, 42
    vertices / quasi-uniform, 162 vertices), scheme, kernel and dtype, the second tagged; their meshes,
    trajectories and spectra are written the way the workflow lays them out (about 2 s)."""
    from vesicle_core.analysis.spectra import spectra_from_trajectory
    from vesicle_core.geometry import mesh as M
    from vesicle_core.solver.simulate import run

    root = tmp_path_factory.mktemp("real") / "results"
    delta, S = 0.17, 100.0
    cases = {
        "A": {"mesh": M.make_vesicle("icosphere", level=1), "id_kw": {"family": "icosphere", "level": 1},
              "cfg": {"scheme": "projection", "kernel": "peskin4", "dtype": "float64"}},
        "B": {"mesh": M.make_vesicle("quasiuniform", n_vertices=162),
              "id_kw": {"family": "quasiuniform", "n_vertices": 162, "tag": "alt"},
              "cfg": {"scheme": "explicit", "kernel": "roma3", "dtype": "float32"}},
    }
    paths = []
    for c in cases.values():
        m = c["mesh"]
        c["id"] = Ci.case_id(delta, S=S, N=16, **c["id_kw"])
        mp = root / "meshes" / f"{Ci.mesh_id(delta, m.attrs['family'], max(m.attrs['level'], 0), m.n_vertices)}.nc"
        mp.parent.mkdir(parents=True, exist_ok=True)
        M.save(m, mp)
        cfg = unit_run(chi=20.0, N=16, stretch=0.05, t_end=0.05, output_every=0.05, Lambda=2e4, K_volume=1e6,
                        **c["cfg"])
        traj = run(m, cfg, root / "runs" / c["id"], progress=False)
        with xr.open_dataset(traj) as ds:
            spec = spectra_from_trajectory(ds.load(), command="pytest")
        sp = traj.parent / "spectra.nc"
        spec.to_netcdf(sp)
        c["paths"] = {"mesh": mp, "trajectory": traj, "spectra": sp}
        paths += [mp, traj, sp]
    C.write_catalog(paths, root / "catalog.csv")
    return root, cases


def test_catalog_columns_of_real_runs(real_runs):
    root, cases = real_runs
    table = _csv_table(root / "catalog.csv")
    assert set(NEW_COLUMNS) <= set(table[0])
    by_path = {r["path"]: r for r in table}
    assert len(table) == 6
    for c in cases.values():
        m = c["mesh"]
        for kind, p in c["paths"].items():
            r = by_path[str(p.relative_to(root))]
            assert r["kind"] == kind
            assert r["n_vertices"] == str(m.n_vertices)
            assert r["mesh_family"] == m.attrs["family"]
            if kind == "mesh":
                assert r["scheme"] == r["dtype"] == r["kernel"] == r["tag"] == ""
                continue
            assert (r["scheme"], r["kernel"], r["dtype"]) == (c["cfg"]["scheme"], c["cfg"]["kernel"],
                                                                c["cfg"]["dtype"])
            assert r["tag"] == c["id_kw"].get("tag", "") and r["case_id"] == c["id"] and r["N"] == "16"
            with xr.open_dataset(p) as ds:
                assert set(ast.literal_eval(r["variables"])) == set(ds.data_vars)  # a list literal
                if kind == "spectra":  # the values between the frames beside the frame values
                    for name in ("l_star", "t_star", "l_star_fit", "t_star_fit"):
                        v = float(ds[name])
                        assert (r[name] == "") if math.isnan(v) else float(r[name]) == v, name
    assert {by_path[str(c["paths"]["mesh"].relative_to(root))]["n_vertices"] for c in cases.values()} == {"42", "162"}


def test_open_sweep_selects_by_mesh_and_run_columns(real_runs):
    root, cases = real_runs
    A, B = cases["A"], cases["B"]
    with pytest.raises(C.CatalogError, match="two spectra datasets") as exc:
        Sw.open_sweep(root / "catalog.csv")
    for c in ("n_vertices=...", "mesh_family=...", "scheme=...", "dtype=...", "kernel=...", "tag=..."):
        assert c in str(exc.value)  # the error names the columns that tell the two apart
    expect = {  # selector -> case it must pick
        "n_vertices=42": ({"n_vertices": 42}, A), "n_vertices='162'": ({"n_vertices": "162"}, B),
        "n_vertices=162.0": ({"n_vertices": 162.0}, B), "mesh_family": ({"mesh_family": "icosphere"}, A),
        "scheme": ({"scheme": "explicit"}, B), "kernel": ({"kernel": "peskin4"}, A),
        "dtype": ({"dtype": "float32"}, B), "tag": ({"tag": "alt"}, B), "untagged": ({"tag": ""}, A),
        "untagged None": ({"tag": None}, A), "N and n_vertices": ({"N": 16, "n_vertices": 42}, A),
        "list": ({"scheme": ["inextensible", "projection"]}, A),
    }
    for name, (where, case) in expect.items():
        ds = Sw.open_sweep(root / "catalog.csv", **where)
        assert str(ds.case_id.item()) == case["id"], name
        with xr.open_dataset(case["paths"]["spectra"]) as ref:  # the right file was opened
            assert float(ds.l_star.item()) == float(ref.l_star)
        assert float(ds.n_vertices.item()) == case["mesh"].n_vertices
        assert str(ds.scheme.item()) == case["cfg"]["scheme"] and str(ds.kernel.item()) == case["cfg"]["kernel"]
    with pytest.raises(C.CatalogError, match="no spectra datasets"):
        Sw.open_sweep(root / "catalog.csv", n_vertices=642)
    with pytest.raises(C.CatalogError, match="no spectra datasets"):
        Sw.open_sweep(root / "catalog.csv", scheme="explicit", kernel="peskin4")


def test_old_files_and_missing_attributes(tmp_path):
    """Spectra without run/mesh attributes (older files): kernel defaults to peskin4, the vertex count of an
    icosphere follows from its level, everything unknown is an empty cell."""
    root = tmp_path / "results"
    paths = write_sweep(root, [(0.116, 553.0, 21)], N=64, level=3, theory=False)  # no run attrs at all
    paths += [p for p in write_sweep(root, [(0.116, 553.0, 21)], N=64, family="quasiuniform", n_vertices=2562,
                                     tag="q", theory=False, run_attrs={"scheme": "projection", "dtype": "float64",
                                                                        "kernel": "bao6"}) if p.name == "spectra.nc"]
    bare = root / "runs" / "D0.5_S10" / "spectra.nc"  # an id without grid or mesh, a dataset without attributes
    bare.parent.mkdir(parents=True)
    ds = synthetic_spectra(0.5, 10.0)
    ds.attrs = {}
    ds.to_netcdf(bare)
    C.write_catalog(sorted(set(paths)) + [bare], root / "catalog.csv")
    rows = {r["case_id"]: r for r in _csv_table(root / "catalog.csv")}
    old = rows["D0.116_S553_N64_L3"]
    assert (old["n_vertices"], old["mesh_family"], old["scheme"], old["dtype"], old["kernel"], old["tag"]) == (
        "642", "icosphere", "", "", "peskin4", "")
    q = rows["D0.116_S553_N64_Q2562_q"]
    assert (q["n_vertices"], q["mesh_family"], q["mesh_level"], q["scheme"], q["kernel"], q["tag"]) == (
        "2562", "quasiuniform", "", "projection", "bao6", "q")
    b = rows["D0.5_S10"]
    assert (b["N"], b["n_vertices"], b["mesh_family"], b["mesh_level"], b["scheme"], b["dtype"], b["tag"]) == (
        "", "", "", "", "", "", "")
    assert b["kernel"] == "peskin4" and b["S"] == "10"
    # files written before the coupling and tension-space options ran with the kernel coupling and triangle tension
    assert (old["coupling"], old["tension_space"], q["coupling"], q["tension_space"]) == (
        "kernel", "triangle", "kernel", "triangle")
    fit = next(r for r in rows.values() if r["kind"] == "fit")
    assert all(fit[c] == "" for c in NEW_COLUMNS)
    # the two N = 64 cases that differ only in the mesh are told apart
    assert str(Sw.open_sweep(root, N=64, n_vertices=642).case_id.item()) == "D0.116_S553_N64_L3"
    assert str(Sw.open_sweep(root, N=64, n_vertices="2562").case_id.item()) == "D0.116_S553_N64_Q2562_q"
    assert str(Sw.open_sweep(root, N=64, scheme="projection").case_id.item()) == "D0.116_S553_N64_Q2562_q"
    assert str(Sw.open_sweep(root, N=None).case_id.item()) == "D0.5_S10"  # None selects empty cells


def test_selector_errors_name_the_columns(tmp_path):
    root = tmp_path / "results"
    C.write_catalog(write_sweep(root, [(0.116, 553.0, 21)], theory=False), root / "catalog.csv")
    with pytest.raises(C.CatalogError) as exc:
        Sw.open_sweep(root / "catalog.csv", n_vertex=642)
    msg = str(exc.value)
    assert "'n_vertex'" in msg and all(c in msg for c in C.COLUMNS)
    with pytest.raises(ValueError, match="numeric column"):  # CatalogError is a ValueError
        Sw.open_sweep(root / "catalog.csv", n_vertices="many")
    # a catalog written before these columns existed: selecting by one says to rebuild it
    table = _csv_table(root / "catalog.csv")
    keep = [c for c in table[0] if c not in NEW_COLUMNS + ("variables",)]
    with open(root / "old.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, keep, extrasaction="ignore")
        w.writeheader()
        w.writerows(table)
    assert str(Sw.open_sweep(root / "old.csv", N=32).case_id.item()) == "D0.116_S553_N32_L3"
    with pytest.raises(C.CatalogError, match="rebuild the catalog") as exc:
        Sw.open_sweep(root / "old.csv", n_vertices=642)
    assert "n_vertices" in str(exc.value) and "'scheme'" not in str(exc.value)


def _rows():
    """Rows as read_catalog returns them (integers or None, NaN for empty floats, "" for empty text)."""
    table = [("a", 64, 642, "projection", "", 553.0), ("b", 64, 2562, "explicit", "fine", 553.0),
             ("c", 32, 642, "projection", "fine", 1106.5), ("d", None, None, "", "", math.nan)]
    return [{"case_id": cid, "N": N, "n_vertices": nv, "scheme": scheme, "tag": tag, "S": S,
             "variables": ("l_star", "sigma")} for cid, N, nv, scheme, tag, S in table]


@pytest.mark.parametrize("use_pandas", [True, False])
@pytest.mark.parametrize("where, expect", [
    ({}, "abcd"),
    ({"N": 64}, "ab"),
    ({"N": "64", "n_vertices": "642"}, "a"),
    ({"n_vertices": np.int64(642)}, "ac"),
    ({"S": 553.0000000001}, "ab"),  # floats to 1e-9 relative
    ({"S": 553.1}, ""),
    ({"scheme": "projection"}, "ac"),
    ({"scheme": ["explicit", ""]}, "bd"),
    ({"tag": ""}, "ad"),
    ({"N": None}, "d"),
    ({"variables": "sigma"}, "abcd"),
    ({"variables": "u_real"}, ""),
])
def test_select_rows_with_and_without_pandas(monkeypatch, use_pandas, where, expect):
    if not use_pandas:
        monkeypatch.setattr(Sw, "_pandas", lambda: None)
    else:
        assert Sw._pandas() is not None
    columns = ["case_id", "N", "n_vertices", "scheme", "tag", "S", "variables"]
    got = Sw.select_rows(_rows(), columns, where)
    assert "".join(r["case_id"] for r in got) == expect


# --------------------------------------------------------------------------- intake-esm
def test_catalog_json_opens_with_intake_esm(tmp_path, monkeypatch):
    """The JSON is an ESM collection intake-esm can open, search and load (optional dependency)."""
    pytest.importorskip("intake_esm")
    import intake

    root = tmp_path / "results"
    paths = write_sweep(root, [(0.116, 553.0, 21), (0.116, 1106.5, 31)])
    paths += [p for p in write_sweep(root, [(0.116, 553.0, 11)], N=64, theory=False) if p.name == "spectra.nc"]
    C.write_catalog(sorted(set(paths)), root / "catalog.csv")
    monkeypatch.chdir(tmp_path)  # not the catalog's directory: catalog_file must resolve next to the JSON
    cat = intake.open_esm_datastore(str(root / "catalog.json"))
    assert len(cat.df) == 7 and list(cat.df.columns) == list(C.COLUMNS)
    keys = set(cat.keys())
    assert {"spectra.D0.116_S553_N32_L3", "spectra.D0.116_S553_N64_L3", "theory.D0.116_S553", "fit.lstar_vs_S",
            "mesh.icosphere_L3_D0.116"} <= keys and len(keys) == 7
    # the catalog_file is the typed Parquet copy: numbers are numbers
    assert json.loads((root / "catalog.json").read_text())["catalog_file"] == "catalog.parquet"
    assert cat.df["N"].dtype.kind == "i" or str(cat.df["N"].dtype) == "Int64", cat.df.dtypes
    assert cat.df["S"].dtype.kind == "f"
    assert list(cat.search(kind="spectra", N=64).df["case_id"]) == ["D0.116_S553_N64_L3"]
    assert list(cat.df[cat.df["N"] == 64]["case_id"]) == ["D0.116_S553_N64_L3"]
    assert len(cat.search(kind="spectra", S=553).df) == 2
    assert cat.search(kind="spectra", N="64").df.empty  # text no longer matches
    assert set(cat.search(variables=".*'Delta_tilde_l'.*").df["kind"]) == {"spectra"}
    # asset paths are relative to the catalog; intake-esm opens them from the working directory
    monkeypatch.chdir(root)
    dsets = cat.search(kind="spectra", N=64).to_dataset_dict(progressbar=False)
    ds = dsets["spectra.D0.116_S553_N64_L3"]
    with xr.open_dataset(root / "runs" / "D0.116_S553_N64_L3" / "spectra.nc") as ref:
        np.testing.assert_array_equal(ds["Delta_l"].values, ref["Delta_l"].values)


# --------------------------------------------------------------------------- typed Parquet catalog
def test_parquet_catalog_is_typed_and_matches_the_csv(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    root = tmp_path / "results"
    paths = write_sweep(root, [(0.116, 553.0, 21), (0.116, 1106.5, 31)])
    rows = C.write_catalog(paths, root / "catalog.csv")
    assert json.loads((root / "catalog.json").read_text())["catalog_file"] == "catalog.parquet"
    table = pq.read_table(root / "catalog.parquet")
    assert table.column_names == list(C.COLUMNS)
    types = {f.name: str(f.type) for f in table.schema}
    assert {types[c] for c in C.INTEGER_COLUMNS} == {"int64"}
    assert {types[c] for c in set(C.NUMERIC_COLUMNS) - set(C.INTEGER_COLUMNS)} == {"double"}
    assert types["kind"] == types["path"] == "string"
    got = table.to_pylist()
    assert [r["path"] for r in got] == [r["path"] for r in rows]
    assert [r["N"] for r in got] == [r["N"] for r in rows]
    mesh = next(r for r in got if r["kind"] == "mesh")
    assert mesh["S"] is None and mesh["N"] is None  # empty cells are nulls, not NaN or text
    # read_catalog given the JSON reads the CSV beside the Parquet file: same rows
    assert [r["path"] for r in C.read_catalog(root / "catalog.json")] == [r["path"] for r in rows]


def test_catalog_without_parquet_points_at_the_csv(tmp_path, monkeypatch):
    root = tmp_path / "results"
    paths = write_sweep(root, [(0.116, 553.0, 21)])
    C.write_catalog(paths, root / "catalog.csv", parquet=False)
    assert json.loads((root / "catalog.json").read_text())["catalog_file"] == "catalog.csv"
    # without pyarrow the default writes the CSV alone and drops a stale typed copy; asking for it is an error
    (root / "catalog.parquet").write_text("stale")
    monkeypatch.setattr(C, "have_pyarrow", lambda: False)
    C.write_catalog(paths, root / "catalog.csv")
    assert not (root / "catalog.parquet").exists()
    assert json.loads((root / "catalog.json").read_text())["catalog_file"] == "catalog.csv"
    with pytest.raises(C.CatalogError, match="pyarrow"):
        C.write_catalog(paths, root / "catalog.csv", parquet=True)
