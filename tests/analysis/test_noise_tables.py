"""vesicle_core.analysis.noise_tables: the ensemble dataset from synthetic runs and stochastic PA ensembles."""

import math

import numpy as np
import pytest
import xarray as xr

from vesicle_core.analysis import noise_tables as NT
from vesicle_core.analysis import stochastic_pa as SP
from vesicle_core.errors import ConfigError

TOP = 10 * (2224.0 / 553.0) ** 0.4


def _rows(delta, S, N, nv, kT, values, key="l_star"):
    return [{"delta": delta, "S": S, "N": N, "vertices": nv, "kT": kT, "noise_seed": k, "l_star": v,
             "l_peak": round(v), "t_star": 0.1} for k, v in enumerate(values)]


def _pa(delta, S, kT, N, values):
    ds = xr.Dataset({"l_star": ("seed", np.asarray(values, float)), "l_peak": ("seed", np.round(values)),
                     "t_star": ("seed", np.full(len(values), 0.12))})
    ds.attrs.update(delta=delta, S=S, kT=kT, grid_N=N)
    return ds


def test_ensemble_dataset_points_exponent_kT_scan_and_rungs():
    d = np.array([-1.0, 0.0, 1.0, 0.5, -0.5])
    rows = []
    for S in (553.0, 2224.0):
        rows += _rows(0.116, S, 128, 9512, 0.0405, 10 * (S / 553) ** 0.4 + d)
    rows += _rows(0.116, 2224.0, 128, 9512, 0.405, TOP - 2 + d)         # one decade up: 2 lower
    rows += _rows(0.116, 2224.0, 192, 21398, 0.0405, TOP * 1.01 + d)    # the finer rung, 1% apart
    rows += [{"delta": 0.116, "S": 2224.0, "N": 128, "vertices": 9512, "kT": 0.0, "noise_seed": 0, "l_star": 25.0,
              "l_peak": 25.0, "t_star": 0.1}]
    pas = [_pa(0.116, 2224.0, 0.0405, 128, [TOP / 1.1] * 15 + [TOP / 1.1 + 1e-9]),
           _pa(0.116, 2224.0, 0.0405, 0, [20.0, 22.0])]
    ens = NT.ensemble_dataset(rows, pas, n_boot=200)
    assert ens.sizes["point"] == 4
    i = int(np.flatnonzero((ens.point_S.values == 2224) & (ens.point_kT.values == 0.0405)
                           & (ens.point_N.values == 128))[0])
    assert ens.point_l_star_mean[i] == pytest.approx(TOP)
    assert ens.point_l_star_sd[i] == pytest.approx(np.std(d, ddof=1))
    assert ens.point_det_l_star[i] == 25.0 and ens.point_n_seeds[i] == 5
    assert ens.point_gpa_excess[i] == pytest.approx(0.1, rel=1e-6) and ens.point_pa_l_star_mean[i] == 21.0
    j = int(np.flatnonzero(ens.point_S.values == 553)[0])
    assert math.isnan(float(ens.point_gpa_excess[j])) and int(ens.point_gpa_n_seeds[j]) == 0
    ibm = np.flatnonzero((ens.exponent_source.values == "ibm") & (ens.exponent_N.values == 128)
                         & (ens.exponent_kT.values == 0.0405))
    assert ens.exponent_exponent[ibm[0]] == pytest.approx(0.4, abs=1e-9)
    assert ens.exponent_ci_low[ibm[0]] < 0.4 < ens.exponent_ci_high[ibm[0]]
    k = np.flatnonzero(ens.kt_source.values == "ibm")
    assert len(k) == 1 and ens.kt_slope[k[0]] == pytest.approx(-2.0)
    assert ens.sizes["rung"] == 1 and bool(ens.rung_met[0]) and ens.rung_rel_diff[0] == pytest.approx(-1 / 101)


def test_ensemble_dataset_needs_noisy_runs():
    with pytest.raises(ConfigError, match="no noisy runs"):
        NT.ensemble_dataset(_rows(0.116, 553.0, 16, 162, 0.0, [10.0]))


def test_stochastic_pa_dataset_keeps_every_seed():
    run = SP.simulate(0.116, 553, seeds=range(3), kT_over_kappa=0.0405, l_max=12, n_steps=60)
    ds = NT.stochastic_pa_dataset(run, N=16, L=5.0, kernel="bao6", coupling="sharp", n_steps=60)
    assert ds.sizes == {"seed": 3, "l": 13, "time": 60}
    np.testing.assert_array_equal(ds.l_star.values, run.l_star)
    assert ds.attrs["grid_N"] == 16 and ds.attrs["kT"] == pytest.approx(0.0405)
