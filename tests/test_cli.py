import subprocess
import sys

import pytest

from vesicle_core import mesh as M
from vesicle_core.cli import main


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
