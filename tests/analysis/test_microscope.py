"""``vesicle microscope`` end to end on a synthetic trajectory whose outline is known (analysis/microscope.py), and
the morphology over the trajectory that it stores (analysis/morphology_series.py)."""

import math

import numpy as np
import pytest
import xarray as xr

from vesicle_core.analysis.microscope import default_radius_um, microscope_from_trajectory
from vesicle_core.analysis.morphology_series import PAPER_TIMES, morphology_frames
from vesicle_core.analysis.surface_calculus import HeatSmoother
from vesicle_core.analysis.wrinkle_location import wrinkle_location
from vesicle_core.cli import main
from vesicle_core.errors import ConfigError
from vesicle_core.geometry import ylm as Yl
from vesicle_core.geometry.mesh import icosphere

L = 10


def _trajectory(times=(-0.5, 0.0, 0.5, 1.0), eps=(0.0, 0.0, 0.01, 0.02)):
    """A sphere of level 4 whose sectoral Y_10,10 wrinkle grows: the outline in z = 0 is 1 + eps cos(10 phi)."""
    v, f = icosphere(4)
    y = Yl.ylm(L, np.arccos(v[:, 2]), np.arctan2(v[:, 1], v[:, 0]))[L, 2 * L].real
    y /= np.abs(y).max()
    X = np.array([v * (1 + e * y)[:, None] for e in eps])
    nt, nf = len(times), len(f)
    zeros = np.zeros(nt)
    data = {"node_x": (("time", "n_node"), X[..., 0]), "node_y": (("time", "n_node"), X[..., 1]),
            "node_z": (("time", "n_node"), X[..., 2]),
            "face_node_connectivity": (("n_face", "n_vertex_per_face"), f.astype(np.int32)),
            "face_tension": (("time", "n_face"), np.zeros((nt, nf))), "tension": ("time", zeros),
            "area": ("time", zeros), "volume": ("time", zeros), "bending_energy": ("time", zeros),
            "tension_energy": ("time", zeros), "area_drift": ("time", zeros), "volume_drift": ("time", zeros)}
    return xr.Dataset(data, coords={"time": ("time", np.asarray(times, float))},
                      attrs={"delta": 0.116, "complete": 1, "wall_time_s": 1000.0})


def test_microscope_reads_the_growing_wrinkle():
    ds = microscope_from_trajectory(_trajectory(), n_images=2)
    assert ds.attrs["radius_um"] == pytest.approx(16.71)
    assert math.isnan(ds.k_star.values[0]) and ds.crests.values[0] == 0
    for name in ("k_star", "k_star_section"):
        assert np.allclose(ds[name].values[2:], L, rtol=0.03), ds[name].values
    for name in ("crests", "up_crossings", "crests_section", "up_crossings_section"):
        assert list(ds[name].values[2:]) == [L, L]
    # the wrinkle's amplitude: eps / sqrt(2) in R, through the image as through the section, less the 4 % that
    # the level-4 polygon's chords cut off a wave of 9 edges (1 - (k h)^2 / 12)
    assert ds.wrinkle_rms_section.values[3] == pytest.approx(0.02 / math.sqrt(2) * 0.96, rel=0.02)
    assert ds.wrinkle_rms.values[3] == pytest.approx(ds.wrinkle_rms_section.values[3], rel=0.03)
    assert np.all(ds.outline_mismatch.values < 0.2)
    assert ds.image.shape[0] == 2 and list(ds.image_time.values) == [0.0, 1.0]
    # a sectoral pattern spreads its variance evenly around the outline
    var = ds.variance_by_angle.values[3]
    assert var.max() / var.min() < 1.5


def test_default_radius_follows_the_paper():
    assert default_radius_um(0.116) == 16.71 and default_radius_um(0.997) == 18.0


def test_command_writes_the_dataset(tmp_path, capsys):
    traj = tmp_path / "trajectory.nc"
    _trajectory().to_netcdf(traj)
    out = tmp_path / "microscope.nc"
    assert main(["microscope", str(traj), "-o", str(out), "--quiet", "--image-times", "0.4", "1.0", "--n-theta",
                 "256"]) == 0
    assert "wrote" in capsys.readouterr().out
    with xr.open_dataset(out) as ds:
        assert ds.attrs["Conventions"].startswith("CF")
        assert ds.sizes["theta"] == 256 and list(ds.image_time.values) == [0.5, 1.0]
        assert ds.k_star.attrs["long_name"].startswith("k_*")


@pytest.mark.parametrize(("args", "name"), [(["--offset", "3"], "offset"), (["--n-theta", "8"], "--n-theta"),
                                            (["--na", "0"], "--na")])
def test_command_names_bad_arguments(tmp_path, capsys, args, name):
    traj = tmp_path / "trajectory.nc"
    _trajectory().to_netcdf(traj)
    with pytest.raises(SystemExit) if name.startswith("--") else _no_raise():
        rc = main(["microscope", str(traj), "-o", str(tmp_path / "m.nc"), "--quiet", *args])
        assert rc == 2
    assert name in capsys.readouterr().err


class _no_raise:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_docs_list_exactly_the_variables_of_microscope_nc():
    import re
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "reference" / "datasets.md").read_text()
    section = doc.split("## microscope.nc: the virtual microscope")[1].split("\n## ")[0]
    listed = {name for row in section.splitlines() if row.startswith("| `")
              for name in re.findall(r"`([a-z_0-9]+)`", row.split("|")[1])}
    ds = microscope_from_trajectory(_trajectory(times=(0.0, 0.5), eps=(0.0, 0.01)), n_images=1, n_theta=64)
    assert listed == set(ds.data_vars) | {"time", "theta", "k", "sector", "image_time", "morph_time", "level", "scale",
                                          "band"} | ({"t_tau"} & listed)

def test_frames_are_the_stride_t_star_and_the_papers_times_inside_the_run():
    time = np.round(np.arange(-0.2, 1.0001, 0.05), 10)
    fr = morphology_frames(time, t_star=0.23, stride=4)
    t = time[fr["index"]]
    # every 4th frame from t = 0 (0, 0.2, ..., 1.0), t_* -> 0.25 (the nearest frame), the paper's 0.5 and 1.0
    assert list(np.round(t, 2)) == [0.0, 0.2, 0.25, 0.4, 0.5, 0.6, 0.8, 1.0]
    assert time[fr["t_star"]] == pytest.approx(0.25)
    assert sorted(fr["paper"]) == [0.0, 0.5, 1.0] and fr["paper_outside"] == [1.46, 2.0, 2.33]
    assert set(PAPER_TIMES) == set(fr["paper"]) | set(fr["paper_outside"])
    # no t_*: nothing is marked; nothing before the reversal is classified
    fr = morphology_frames(time, t_star=None, stride=100)
    assert fr["t_star"] == -1 and np.all(time[fr["index"]] >= 0)
    with pytest.raises(ConfigError, match="stride"):
        morphology_frames(time, stride=0)


def test_microscope_classifies_the_sectoral_wrinkle_as_ripples_at_t_star():
    traj = _trajectory(times=(-0.5, 0.0, 0.5, 1.0), eps=(0.0, 0.002, 0.01, 0.02))
    ds = microscope_from_trajectory(traj, spectra=xr.Dataset({"t_star": 1.0}), n_images=0, n_theta=128,
                                    morphology_stride=1)
    assert list(ds.morph_time.values) == [0.0, 0.5, 1.0]
    assert list(ds.is_t_star.values) == [0, 0, 1] and ds.attrs["t_star"] == 1.0
    assert list(ds.paper_time.values) == [0.0, 0.5, 1.0]
    assert list(ds.attrs["paper_times_outside"]) == [1.46, 2.0, 2.33]
    # Y_10,10: ten crests along the meridians, all winding round z: ripples, l_c = 10, no low-degree lobes
    assert ds.attrs["pattern_at_t_star"] == "ripples"
    assert ds.pattern.attrs["flag_meanings"].split()[int(ds.pattern.values[-1])] == "ripples"
    assert ds.l_c.values[-1] == pytest.approx(10, rel=0.05) and ds.low_degree_fraction.values[-1] < 0.05
    # the bands about x share out all the wrinkle energy; the synthetic run's tension is 0 everywhere, so there is no
    # correlation with it to report
    assert ds.energy_fraction.values[-1].sum() == pytest.approx(1.0)
    assert np.isnan(ds.tension_correlation.values[-1])
    assert ds.attrs["cost_fraction"] == pytest.approx(
        (ds.attrs["microscope_wall_time_s"] + ds.attrs["morphology_wall_time_s"]) / 1000.0)
    assert "l_c" not in microscope_from_trajectory(traj, n_images=0, n_theta=64, morphology_stride=None)


def test_a_shared_smoother_must_have_the_energy_smoothing_length():
    v, f = icosphere(3)
    h = v[:, 0] * v[:, 1]
    with pytest.raises(ConfigError, match="smoother"):
        wrinkle_location(v, f, h, (1, 0, 0), smoothing=0.3, smoother=HeatSmoother(v, f, 0.2))
    a = wrinkle_location(v, f, h, (1, 0, 0), smoothing=0.3)
    b = wrinkle_location(v, f, h, (1, 0, 0), smoothing=0.3, smoother=HeatSmoother(v, f, 0.3))
    assert np.allclose(a.enrichment, b.enrichment, rtol=1e-12)


def test_a_run_that_reaches_every_paper_time_writes_and_reads_back(tmp_path):
    from vesicle_core.data.datasets import write_dataset
    from vesicle_core.validation.claims import case_row

    traj = _trajectory(times=(0.0, 0.5, 1.0, 1.5, 2.0, 2.4), eps=(0.0, 0.005, 0.01, 0.015, 0.02, 0.02))
    ds = microscope_from_trajectory(traj, spectra=xr.Dataset({"t_star": 2.0}), n_images=0, n_theta=64,
                                    morphology_stride=10)
    write_dataset(ds, tmp_path / "m.nc")
    with xr.open_dataset(tmp_path / "m.nc") as back:
        row = case_row("c", back.load())
    assert row["paper_outside"] == [] and sorted(row["paper"]) == [0.0, 0.5, 1.0, 1.46, 2.0, 2.33]
    assert row["pattern_t_star"] == "ripples" and row["t_star"] == 2.0
