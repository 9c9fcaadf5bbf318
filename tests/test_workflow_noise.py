"""The noisy-ensemble configs plan (issue 49): config/thermal_converged.yaml on top of the default config, and the
tiny CI copy; (slow) the tiny copy runs the noise chain end to end."""

import pytest
import yaml
from test_workflow import ROOT, planned_jobs, snakemake, workflow_copy


def _sims(jobs):
    return {j["wildcards"]["case_id"]: j for j in jobs if j["rule"] == "simulate"}


def test_thermal_converged_config_plans_the_issue_set(tmp_path):
    """Delta = 0.116 at five S and 0.997 at two (mesh_ale shape), 8 seeds each at kT 0.0405 on 128^3 and the
    9512-vertex mesh, kT x0.1 and x10 at S = 553 and 2224, a 192^3 rung (21398 vertices, 4 seeds), the deterministic
    twins, and the stochastic PA beside every noisy point in the continuum and on its grid (16 seeds)."""
    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "-n", "-p", "--configfile", "config/thermal_converged.yaml")
    assert r.returncode == 0, r.stderr + r.stdout
    jobs = planned_jobs(r.stdout)
    sims = _sims(jobs)
    seeds8, five = range(8), ("227", "553", "1106.5", "2224", "4448")
    want = {f"D0.116_S{S}_N128_Q9512_kT0.0405_n{k}" for S in five for k in seeds8}
    want |= {f"D0.997_S{S}_N128_Q9512_kT0.0405_n{k}" for S in ("237", "947") for k in seeds8}
    want |= {f"D0.116_S{S}_N128_Q9512_kT{kT}_n{k}" for S in ("553", "2224") for kT in ("0.00405", "0.405")
             for k in seeds8}
    want |= {f"D0.116_S{S}_N192_Q21398_kT0.0405_n{k}" for S in ("553", "2224") for k in range(4)}
    want |= {f"D0.116_S{S}_N128_Q9512" for S in five} | {f"D0.997_S{S}_N128_Q9512" for S in ("237", "947")}
    assert set(sims) == want
    noisy_elongated = r.stdout.count("\nmesh_ale: shape\n")
    assert noisy_elongated == 2 * 8 + 2  # the elongated ensembles and their deterministic twins
    spa = [j for j in jobs if j["rule"] == "stochastic_pa"]
    # continuum per (Delta, S, kT): 7 + 4; on the grid: the same at 128^3, and 2 more at 192^3
    assert len(spa) == 2 * 11 + 2
    assert "--seeds 16" in r.stdout and "--grid-N 192 --L 5.0 --kernel bao6 --coupling sharp" in r.stdout
    assert sum(j["rule"] in ("noise_analysis", "noise_figures") for j in jobs) == 2


def test_thermal_tiny_config_is_small():
    cfg = yaml.safe_load((ROOT / "config" / "thermal_tiny.yaml").read_text())
    assert cfg["run"]["N"] == 16 and cfg["mesh"] == {"family": "icosphere", "level": 2}  # 162 vertices
    kTs = {g["run"]["kT"] for g in cfg["sweep"] if "noise_seeds" in g}
    assert len(kTs) == 2 and all(len(g["noise_seeds"]) == 3 for g in cfg["sweep"] if "noise_seeds" in g)


@pytest.mark.slow
def test_thermal_tiny_runs_the_noise_chain(tmp_path):
    """`snakemake noise` on config/thermal_tiny.yaml: runs, stochastic PA, ensembles.nc, the noise figures."""
    import xarray as xr

    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "--cores", "2", "noise", "--configfile", "config/thermal_tiny.yaml", timeout=900)
    assert r.returncode == 0, r.stderr[-5000:] + r.stdout[-3000:]
    with xr.open_dataset(wd / "results" / "noise" / "ensembles.nc") as ens:
        assert ens.sizes["point"] == 3 and (ens["point_n_seeds"].values == 3).all()
        assert (ens["point_pa_n_seeds"].values == 16).all() and (ens["point_gpa_n_seeds"].values == 16).all()
        assert ens.sizes["kt_scan"] >= 1
    for name in ("lstar_vs_S.png", "lstar_hist.png"):
        assert (wd / "results" / "figures" / "noise" / name).stat().st_size > 10_000
