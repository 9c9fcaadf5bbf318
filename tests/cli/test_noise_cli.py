"""`vesicle stochastic-pa` and the noise figures (vesicle_core.viz.noise_figures) on small synthetic inputs."""

import numpy as np
import pytest
import xarray as xr

from vesicle_core.analysis import noise_tables as NT
from vesicle_core.cli import main
from vesicle_core.viz import noise_figures as NF


def test_stochastic_pa_command_writes_every_seed(tmp_path):
    out = tmp_path / "pa.nc"
    rc = main(["stochastic-pa", "--delta", "0.116", "--S", "553", "--kT", "0.0405", "--seeds", "3", "--n-steps", "60",
               "--l-max", "12", "--grid-N", "32", "--L", "5", "--coupling", "sharp", "-o", str(out)])
    assert rc == 0
    with xr.open_dataset(out) as ds:
        assert ds.sizes["seed"] == 3 and ds.attrs["grid_N"] == 32 and ds.attrs["coupling"] == "sharp"
        assert np.isfinite(ds["l_star"].values).all()


def test_stochastic_pa_command_refuses_a_one_seed_ensemble(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["stochastic-pa", "--delta", "0.116", "--S", "553", "--kT", "0.0405", "--seeds", "1", "-o",
              str(tmp_path / "x.nc")])
    assert e.value.code == 2 and "--seeds" in capsys.readouterr().err


def test_point_ids_group_the_seeds():
    assert NF.point_id("D0.116_S553_N128_Q9512_kT0.0405_n7") == "D0.116_S553_N128_Q9512_kT0.0405"
    rows = [{"case_id": f"D0.116_S553_N16_L2_kT0.0405_n{k}", "kT": 0.0405, "noise_seed": k} for k in (2, 0, 1)]
    rows.append({"case_id": "D0.116_S553_N16_L2", "kT": 0.0, "noise_seed": 0})
    groups = NF.point_members(rows)
    assert list(groups) == ["D0.116_S553_N16_L2_kT0.0405"] and [r["noise_seed"] for r in groups[
        "D0.116_S553_N16_L2_kT0.0405"]] == [0, 1, 2]


def _spectra(seed, t_star):
    t = np.linspace(-0.1, 0.5, 31)
    l = np.arange(0, 13)
    rng = np.random.default_rng(seed)
    Dl = np.exp(-((t[:, None] - t_star) ** 2) * 40) * (1 + 0.1 * rng.random((t.size, l.size))) + 1e-3
    ds = xr.Dataset({"sigma": ("time", -50 + 100 * t + rng.standard_normal(t.size)), "Delta_l": (("time", "l"), Dl),
                     "l_star": 8.0 + 0.3 * seed, "l_peak": 8.0, "t_star": t_star}, coords={"time": t, "l": l})
    ds.attrs.update(delta=0.116, S=553.0, N=16, kT=0.0405)
    return ds


def test_noise_figures_are_written(tmp_path):
    rows = [{"delta": 0.116, "S": S, "N": 16, "vertices": 162, "kT": 0.0405, "noise_seed": k,
             "l_star": 8.0 * (S / 553) ** 0.3 + 0.3 * k, "l_peak": 8.0, "t_star": 0.2} for S in (553.0, 2224.0)
            for k in range(3)]
    rows.append({"delta": 0.116, "S": 553.0, "N": 16, "vertices": 162, "kT": 0.0, "noise_seed": 0, "l_star": 7.0,
                 "l_peak": 7.0, "t_star": 0.2})
    pa = xr.Dataset({"l_star": ("seed", [9.0, 9.5, 10.0]), "l_peak": ("seed", [9.0, 10.0, 10.0]),
                     "t_star": ("seed", [0.2, 0.21, 0.19]), "Delta_2": (("seed", "time"), np.ones((3, 5))),
                     "sigma": (("seed", "time"), np.zeros((3, 5)))}, coords={"time": np.linspace(0, 0.5, 5)},
                    attrs={"delta": 0.116, "S": 553.0, "kT": 0.0405, "grid_N": 16})
    ens = NT.ensemble_dataset(rows, [pa], n_boot=50)
    written = NF.plot_lstar_noise(ens, None, [tmp_path / "f4.png", tmp_path / "f4.svg"], dpi=60)
    written += NF.plot_lstar_histograms(ens, [pa], tmp_path / "hist.png", dpi=60)
    sims = [_spectra(k, 0.2 + 0.01 * k) for k in range(3)]
    written += NF.plot_dynamics_noise(sims, _spectra(9, 0.2), pa, tmp_path / "dyn.png", dpi=60)
    assert len(written) == 4 and all(p.stat().st_size > 5000 for p in map(type(tmp_path), written))
