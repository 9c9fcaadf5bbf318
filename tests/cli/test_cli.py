import subprocess
import sys

import pytest

from vesicle_core.cli import main
from vesicle_core.geometry import mesh as M


def test_mesh_command_writes_file_and_reports(tmp_path, capsys):
    out = tmp_path / "m.nc"
    assert main(["mesh", "-o", str(out), "--level", "3", "--axes", "1", "0.8", "1"]) == 0
    text = capsys.readouterr().out
    for word in ("vertices 642", "faces 1280", "Delta", "volume", "area", "edge min/mean/max"):
        assert word in text
    m = M.load(out)
    assert m.n_vertices == 642


def test_mesh_command_target_delta(tmp_path):
    out = tmp_path / "m.nc"
    assert main(["mesh", "-o", str(out), "--level", "3", "--delta", "0.5", "--family", "quasiuniform"]) == 0
    assert M.load(out).excess_area() == pytest.approx(0.5, abs=1e-8)


@pytest.mark.parametrize(
    "args, name",
    [
        (["--radius", "-1"], "--radius"),
        (["--radius", "0"], "--radius"),
        (["--axes", "1", "0", "1"], "--axes"),
        (["--axes", "1", "-0.8", "1"], "--axes"),
        (["--level", "-1"], "--level"),
        (["--level", "40"], "--level"),
        (["--delta", "-0.1"], "--delta"),
        (["--family", "cube"], "--family"),
        (["--colour", "red"], "--colour"),
    ],
)
def test_mesh_command_bad_arguments(tmp_path, args, name):
    r = subprocess.run(
        [sys.executable, "-m", "vesicle_core.cli", "mesh", "-o", str(tmp_path / "x.nc"), *args],
        capture_output=True, text=True,
    )
    assert r.returncode != 0
    assert name in r.stderr
    assert not (tmp_path / "x.nc").exists()


def test_theory_and_fit_commands(tmp_path, capsys):
    import xarray as xr

    paths = []
    for S in (300.0, 600.0, 1200.0):
        p = tmp_path / f"th_{S:g}.nc"
        assert main(["theory", "--delta", "0.116", "--S", str(S), "-o", str(p), "--no-modes", "--n-out", "200"]) == 0
        paths.append(str(p))
    with xr.open_dataset(paths[0]) as ds:
        assert ds.attrs["Conventions"].startswith("CF") and "history" in ds.attrs
        assert ds.attrs["S"] == 300.0 and "l_star" in ds and "sigma" in ds
    out = tmp_path / "fit.nc"
    assert main(["fit", *paths, "-o", str(out)]) == 0
    with xr.open_dataset(out) as f:
        assert f.sizes["case"] == 3 and f.sizes["group"] == 1
        g = f.isel(group=0)
        b = float(g.l_star_exponent)
        assert float(g.l_star_ci_low) <= b <= float(g.l_star_ci_high)
        assert 0.3 < b < 0.5  # PA: l_* grows like S^0.43 (theory.py docstring)
        assert (f.decay_exponent.values > 0).all()


def test_fit_command_names_bad_file(tmp_path, capsys):
    bad = tmp_path / "nothing.nc"
    assert main(["fit", str(bad), "-o", str(tmp_path / "f.nc")]) == 2
    assert "nothing.nc" in capsys.readouterr().err


def test_bench_command_runs(capsys):
    assert main(["bench", "--sizes", "16", "--levels", "1", "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert "step/fft" in out and "forces" in out


def test_set_parses_python_float_notation():
    from vesicle_core.cli.args import parse_set as _parse_set

    # Snakemake hands params to the shell as Python writes them: 2e-05, not YAML's 2.0e-05
    assert _parse_set(["dt=2e-05", "N=64", "Lambda=null", "dt_safety=0.4", "scheme=explicit"]) == {
        "dt": 2e-05, "N": 64, "Lambda": None, "dt_safety": 0.4, "scheme": "explicit"}


def test_run_command_reports_where_the_time_went(tmp_path, capsys):
    import xarray as xr

    from vesicle_core.solver.step_limits import LIMITS, shares_line

    mesh = tmp_path / "mesh.nc"
    assert main(["mesh", "-o", str(mesh), "--level", "2"]) == 0
    from unit_run import UNIT_RUN

    sets = [f"{k}={v}" for k, v in UNIT_RUN.items()]
    sets += ["N=16", "scheme=inextensible", "tension_space=harmonic", "chi=10", "stretch=0.05", "t_end=0.05",
             "output_every=0.025"]
    args = ["run", str(mesh), "-o", str(tmp_path / "run")]
    for kv in sets:
        args += ["--set", kv]
    assert main(args) == 0
    out = capsys.readouterr().out
    with xr.open_dataset(tmp_path / "run" / "trajectory.nc") as ds:
        ds.load()
        at = ds.attrs
    # the Stokes products are part of the call, and every step makes at least one
    assert 0 < at["stokes_s"] < at["wall_time_s_last_call"]
    assert at["stokes_solves"] >= at["steps"] > 0
    # the bending limit's measurement makes Stokes products too (counted in stokes_solves): timed, and in the share
    assert (at["bending_stokes_s"] > 0) == (at["bending_solves"] > 0)
    wall = at["wall_time_s_last_call"]
    share = round(100 * (at["stokes_s"] + at["bending_stokes_s"]) / wall)
    assert f"{at['steps']} steps" in out and f"Stokes products {share}%" in out
    assert f"({round(100 * at['bending_stokes_s'] / wall)}% in the bending limit's measurement)" in out
    # the closing line's shares of the steps by the limit that set them: exact counts from the frames
    counts = {k: int(ds[f"steps_{k}"].sum()) for k in LIMITS}
    assert sum(counts.values()) == at["steps"]
    assert shares_line(counts) in out and out.count("steps: ") == 1
