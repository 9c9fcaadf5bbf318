"""Every physics study in studies/ runs to its end on a tiny grid (seconds), so that a change to the package that
breaks one shows here and not months later when someone reruns it for a docs page.

Each study is run as ``python studies/<name>.py ARGS`` would run it (runpy, ``__main__``), in-process, with size
arguments that make it tiny, on inputs made once per session: a 162-vertex vesicle on a 16^3 grid, deterministic
(a short stretch and reversal) and noisy (no flow), its spectra and its mesh file. The numbers printed are not
checked (the studies' physics is checked by the tests of the modules they call); that each prints its table is.
"""

import runpy
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "studies"


@pytest.fixture(scope="session")
def tiny(tmp_path_factory):
    """Paths of the tiny inputs: mesh.nc, det.nc (an inextensible run through the reversal), det_spectra.nc,
    hot.nc (a noisy run without flow, frames every 2-3 steps)."""
    import xarray as xr

    from vesicle_core.analysis.spectra import spectra_from_trajectory
    from vesicle_core.geometry import mesh as Mm
    from vesicle_core.io import atomic_to_netcdf
    from vesicle_core.model.run_config import DEFAULTS_BEFORE_RECOMMENDED, RunConfig
    from vesicle_core.solver.simulate import run

    d = tmp_path_factory.mktemp("studies")
    m = Mm.make_vesicle("quasiuniform", n_vertices=162, axes=(1.0, 0.8, 1.0))  # the family the thermal runs use
    Mm.save(m, d / "mesh.nc")
    # the studies' inputs in the discretisation they were written for (the defaults before the recommended method)
    base = {**DEFAULTS_BEFORE_RECOMMENDED, "N": 16, "scheme": "inextensible", "tension_space": "harmonic"}
    det = run(m, RunConfig(**{**base, "chi": 50.0, "stretch": 0.05, "t_end": 0.05, "output_every": 0.025}), d / "det",
              progress=False)
    hot = run(m, RunConfig(**{**base, "chi": 0.0, "stretch": 0.0, "t_end": 0.01, "output_every": 0.001, "kT": 0.0405,
                              "noise_seed": 1, "tension_fixed": 10.0}), d / "hot", progress=False)
    with xr.open_dataset(det) as traj:
        atomic_to_netcdf(spectra_from_trajectory(traj.load(), l_max=6), d / "det_spectra.nc")
    return {"mesh": d / "mesh.nc", "det": det, "hot": hot, "spectra": d / "det_spectra.nc", "dir": d}


# per study: its arguments (inputs by key of the `tiny` fixture in braces) and a line its output must contain
CASES = {
    "growth_windows": (["{spectra}", "--windows", "0", "0.025", "0.05", "--l", "3", "4"], "| window | mean sigma |"),
    "mesh_mode_energy": (["{mesh}", "--l-max", "4"], "| 4 |"),
    "mode_regression": (["{hot}", "--starts", "1", "--span", "0.002", "--l-max", "4"], "noisy / deterministic"),
    "noise_step_limit": (["--N", "16", "--vertices", "162", "--kT", "0.405", "--noise-step", "1", "--seeds", "0",
                          "--steps", "3"], "survived"),
    "pa_cutoff": (["--config", str(ROOT / "config" / "validation.yaml"), "--l-max", "16"], "truncation active at S"),
    "stationary_tension": (["--deltas", "0.116", "--L", "5", "--h", "0.3125", "--n-vertices", "162", "--stretch",
                            "0.05", "--out", "{dir}/stationary"], "| 0.116 | "),
    "stochastic_pa": (["--seeds", "2", "--steps", "50", "--equilibrium-seeds", "2", "--equilibrium-steps", "100",
                       "--draws", "20000"], "exact fixed-area ensemble"),
    "step_accuracy": (["{spectra}", "{spectra}", "--l", "3", "4", "--t-max", "0.05"], "| 0.00% | 0.00% |"),
    "tension_modes": (["{det}", "--time", "0.025"], "[10, 100)"),
    "tension_spectrum": (["{det}", "--l-max", "4"], "cb_raw cb_low"),
    "thermal_diffusion": (["--N", "16", "--steps", "20", "--markers", "2", "--lag", "5"], "| sharp | 0."),
    "thermal_equilibrium": (["{hot}", "--l-max", "6"], "| 6 |"),  # l_max >= 5: it fits l = 3..l_max - 2
    "vesicle_diffusion": (["{hot}", "--lags", "0.002"], "| pooled |"),
}


def run_study(name, args, monkeypatch):
    monkeypatch.setattr(sys, "argv", [str(STUDIES / f"{name}.py"), *args])
    runpy.run_path(str(STUDIES / f"{name}.py"), run_name="__main__")


def test_every_study_has_a_smoke_case_and_names_the_docs_it_feeds():
    """A new study gets a case here (or a slow one below), and its docstring says which docs section it feeds."""
    import ast

    names = {p.stem for p in STUDIES.glob("*.py")}
    assert names == set(CASES) | {"thermal_ensemble"}, names ^ (set(CASES) | {"thermal_ensemble"})
    for p in sorted(STUDIES.glob("*.py")):
        doc = ast.get_docstring(ast.parse(p.read_text()))
        assert doc and "Feeds docs/" in doc, f"{p.name}: its docstring names no docs section ('Feeds docs/...')"


# tens of CPU seconds even at these sizes: fixed work beside the size arguments (thermal_diffusion: the N = 64
# hydrodynamic radius and the Ito drift over 32 positions and every vertex; stochastic_pa: ~20 PA ensembles)
SLOW = {"thermal_diffusion", "stochastic_pa"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n for n in sorted(CASES)])
def test_study_runs_on_a_tiny_grid(name, tiny, monkeypatch, capsys):
    args, expect = CASES[name]
    run_study(name, [a.format(**tiny) for a in args], monkeypatch)
    out = capsys.readouterr().out
    assert expect in out, out[-2000:]


@pytest.mark.slow
def test_thermal_ensemble_runs_on_a_tiny_workflow_catalog(tmp_path, monkeypatch, capsys):
    """thermal_ensemble.py reads a workflow catalog with a noisy ensemble and its deterministic run: the tiny grid's
    workflow makes one (one S, two noise seeds and kT = 0; minutes, so slow)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("_workflow_helpers", ROOT / "tests" / "test_workflow.py")
    wf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(wf)
    TINY, snakemake, write_config = wf.TINY, wf.snakemake, wf.write_config
    wd = wf.workflow_copy(tmp_path)
    run = {"scheme": "inextensible", "tension_space": "harmonic", "seed_spectrum": "mesh"}  # noise: no thermal seed
    cfg = {**TINY, "sweep": [{"delta": 0.116, "S": [553], "noise_seeds": [0, 1], "run": {**run, "kT": 0.0405}},
                             {"delta": 0.116, "S": [553], "run": run}]}
    r = snakemake(wd, "results/catalog.csv", "--cores", "2", "--configfile", write_config(wd, cfg), timeout=1800)
    assert r.returncode == 0, (r.stderr + r.stdout)[-3000:]
    monkeypatch.chdir(wd)
    run_study("thermal_ensemble", ["results/catalog.csv", "--kT", "0.0405", "--pa-seeds", "2"], monkeypatch)
    out = capsys.readouterr().out
    assert "| 553 | noise on (2) |" in out, out[-3000:]
