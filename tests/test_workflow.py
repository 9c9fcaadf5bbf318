"""The Snakemake workflow: configs validate (and bad ones fail before any job, naming the key), the sweep table
plans one point per S and reruns only what a change touches, the paper config plans, and (slow) the tiny config
runs end to end. Every test works in a temporary copy of Snakefile, workflow/ and config/."""

import os
import re
import shutil
import sys
from pathlib import Path

import pytest
import yaml
from snakemake_runner import run_snakemake

from vesicle_core.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _env():
    env = dict(os.environ)
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    env.setdefault("MPLBACKEND", "Agg")
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    return env


def workflow_copy(tmp_path):
    dst = tmp_path / "wf"
    dst.mkdir()
    shutil.copy(ROOT / "Snakefile", dst / "Snakefile")
    shutil.copytree(ROOT / "workflow", dst / "workflow")
    shutil.copytree(ROOT / "config", dst / "config")
    return dst


def snakemake(wd, *args, timeout=300):
    """Run snakemake in ``wd`` (targets first: --configfile takes several values)."""
    return run_snakemake(wd, args, _env(), timeout=timeout)


def write_config(wd, cfg, name="test.yaml"):
    path = wd / "config" / name
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return f"config/{name}"


def planned_jobs(text):
    """[{rule, wildcards, output}] from the job listing of a dry run ("rule X:" then 4-space indented lines)."""
    jobs = []
    cur = None
    for line in text.splitlines():
        m = re.match(r"^(?:local)?rule (\w+):\s*$", line)
        if m:
            cur = {"rule": m.group(1), "wildcards": {}, "output": []}
            jobs.append(cur)
        elif cur is not None and line.startswith("    "):
            key, _, val = line.strip().partition(": ")
            if key == "output":
                cur["output"] = [v.strip() for v in val.split(",") if v.strip()]
            elif key == "wildcards":
                cur["wildcards"] = dict(kv.split("=", 1) for kv in val.split(", ") if "=" in kv)
            elif key == "priority":
                cur["priority"] = int(val)
        else:
            cur = None
    return jobs


TINY = {
    "sweep": [{"delta": 0.116, "S": [553, 1106.5, 2224]}],
    "mesh": {"family": "icosphere", "level": 2},
    "run": {"N": 16, "stretch": 0.5, "t_end": 0.3, "output_every": 0.05},
    "theory": {"n_out": 101, "store_modes": False},
}

PER_CASE_RULES = {"simulate", "analyze", "microscope", "figure_dynamics", "figure_wrinkles", "figure_views",
                  "figure_snapshots", "figure_microscope"}
AGGREGATE_RULES = {"fit", "figure_lstar", "catalog", "default", "all"}


# --------------------------------------------------------------------------- sweep planning
def test_changing_one_S_plans_jobs_for_that_point_only(tmp_path):
    wd = workflow_copy(tmp_path)
    cfg_a = write_config(wd, TINY, "a.yaml")
    r = snakemake(wd, "-n", "--configfile", cfg_a)
    assert r.returncode == 0, r.stderr + r.stdout
    jobs = planned_jobs(r.stdout)
    cases = {j["wildcards"]["case_id"] for j in jobs if j["rule"] == "simulate"}
    assert cases == {"D0.116_S553_N16_L2", "D0.116_S1106.5_N16_L2", "D0.116_S2224_N16_L2"}
    assert sum(j["rule"] == "mesh" for j in jobs) == 1  # one mesh shared by the three flow strengths
    # pretend everything was built: every planned output exists, all with one timestamp
    outputs = [wd / o for j in jobs for o in j["output"]]
    assert outputs and all("{" not in str(o) for o in outputs)
    for o in outputs:
        o.parent.mkdir(parents=True, exist_ok=True)
        o.write_bytes(b"")
    for o in outputs:
        os.utime(o, (1.7e9, 1.7e9))
    r = snakemake(wd, "-n", "--configfile", cfg_a)
    assert r.returncode == 0 and "Nothing to be done" in r.stdout + r.stderr, r.stdout

    changed = {**TINY, "sweep": [{"delta": 0.116, "S": [553, 1200, 2224]}]}
    r = snakemake(wd, "-n", "--configfile", write_config(wd, changed, "b.yaml"))
    assert r.returncode == 0, r.stderr + r.stdout
    jobs = planned_jobs(r.stdout)
    rules = {j["rule"] for j in jobs}
    assert "mesh" not in rules  # the mesh depends on mesh parameters only
    per_point = [j for j in jobs if j["rule"] not in AGGREGATE_RULES]
    assert {j["rule"] for j in per_point} == PER_CASE_RULES | {"theory"}
    for j in per_point:
        ident = j["wildcards"].get("case_id") or j["wildcards"].get("theory_id")
        assert ident in ("D0.116_S1200_N16_L2", "D0.116_S1200"), (j["rule"], ident)
    assert rules - PER_CASE_RULES - {"theory"} <= AGGREGATE_RULES  # fit, Fig. 4 and the catalog gather all points


def test_one_sweep_point_by_its_file(tmp_path):
    wd = workflow_copy(tmp_path)
    cfg = write_config(wd, TINY)
    r = snakemake(wd, "results/runs/D0.116_S553_N16_L2/spectra.nc", "-n", "-p", "--configfile", cfg)
    assert r.returncode == 0, r.stderr + r.stdout
    jobs = planned_jobs(r.stdout)
    assert sorted(j["rule"] for j in jobs) == ["analyze", "mesh", "simulate"]
    # parameters reach `vesicle run -c run.yaml` as plain numbers: chi from S and Delta, every run key explicit
    assert "chi: 66.690084708" in r.stdout and "\nN: 16\n" in r.stdout and "\nLambda: null\n" in r.stdout
    assert "-c results/runs/D0.116_S553_N16_L2/run.yaml" in r.stdout
    assert "--delta 0.116" in r.stdout and "--level 2" in r.stdout


def test_an_ensemble_plans_one_case_per_noise_seed(tmp_path):
    """noise_seeds makes the seed a sweep dimension: one run per (S, seed), ids ending in _kT<kT>_n<seed>, the seed
    in the run's parameters, one mesh and one PA per S shared by the members; without kT > 0 it is refused."""
    wd = workflow_copy(tmp_path)
    cfg = {**TINY, "sweep": [{"delta": 0.116, "S": [553, 2224], "noise_seeds": [0, 1, 2],
                              "run": {"scheme": "inextensible", "tension_space": "harmonic", "kT": 0.0405}}]}
    r = snakemake(wd, "-n", "--configfile", write_config(wd, cfg))
    assert r.returncode == 0, r.stderr + r.stdout
    jobs = planned_jobs(r.stdout)
    cases = {j["wildcards"]["case_id"] for j in jobs if j["rule"] == "simulate"}
    assert cases == {f"D0.116_S{S}_N16_L2_kT0.0405_n{k}" for S in (553, 2224) for k in range(3)}
    assert sum(j["rule"] == "mesh" for j in jobs) == 1 and sum(j["rule"] == "theory" for j in jobs) == 2
    r = snakemake(wd, "results/runs/D0.116_S553_N16_L2_kT0.0405_n2/trajectory.nc", "-n", "-p", "--configfile",
                  write_config(wd, cfg))
    assert r.returncode == 0 and "\nkT: 0.0405\n" in r.stdout and "\nnoise_seed: 2\n" in r.stdout, r.stdout[-3000:]
    cold = {**TINY, "sweep": [{"delta": 0.116, "S": [553], "noise_seeds": [0, 1]}]}
    r = snakemake(wd, "-n", "--configfile", write_config(wd, cold, "cold.yaml"))
    assert r.returncode != 0 and "noise_seeds" in r.stdout + r.stderr and "kT" in r.stdout + r.stderr


# --------------------------------------------------------------------------- validation
@pytest.mark.parametrize("patch, key", [
    ({"run": {"N": "sixteen"}}, "N"),                                  # wrong type
    ({"run": {"N": 16, "flux_capacitor": 3}}, "flux_capacitor"),       # unknown key
    ({"mesh": {"level": 12}}, "level"),                                # out of range
    ({"sweep": [{"delta": 0.116, "S": [553, -5]}]}, "S"),              # out of range inside the sweep
    ({"sweep": [{"delta": 0.116, "S": [553], "colour": "red"}]}, "colour"),
    ({"figures": {"vector_format": "gif"}}, "vector_format"),
])
def test_bad_config_fails_before_any_job_naming_the_key(tmp_path, patch, key):
    wd = workflow_copy(tmp_path)
    cfg = {**TINY, **{k: ({**TINY.get(k, {}), **v} if isinstance(v, dict) else v) for k, v in patch.items()}}
    r = snakemake(wd, "--cores", "1", "--configfile", write_config(wd, cfg))
    out = r.stdout + r.stderr
    assert r.returncode != 0
    assert "Error validating config" in out or "ValidationError" in out, out[-2000:]
    assert f"'{key}'" in out or f"['{key}']" in out, out[-2000:]
    assert not (wd / "results").exists()  # nothing ran
    assert not re.search(r"^(local)?rule \w+:", r.stdout, re.M)


def test_duplicate_cases_are_refused(tmp_path):
    wd = workflow_copy(tmp_path)
    cfg = {**TINY, "sweep": [{"delta": 0.116, "S": [553]}, {"delta": 0.116, "S": [553]}]}
    r = snakemake(wd, "-n", "--configfile", write_config(wd, cfg))
    assert r.returncode != 0 and "tag" in r.stdout + r.stderr


def test_config_files_satisfy_schema_and_solver():
    """Every shipped config, merged over config/config.yaml as Snakemake merges a --configfile, validates against the
    schema, and every case's run section (table defaults filled in) is a valid
    vesicle_core.model.run_config.RunConfig; the schema's run keys are exactly RunConfig's (less chi)."""
    import copy
    from dataclasses import fields

    from snakemake.utils import update_config, validate

    from vesicle_core.model.parameters import RUN_PARAMETERS, defaults
    from vesicle_core.model.run_config import RunConfig
    from vesicle_core.model.units import chi_from_S

    schema = ROOT / "workflow" / "schemas" / "config.schema.yaml"
    params_schema = ROOT / "workflow" / "schemas" / "run_parameters.schema.json"
    run_props = yaml.safe_load(params_schema.read_text())["$defs"]["run"]["properties"]
    assert set(run_props) == {f.name for f in fields(RunConfig)} - {"chi"}
    base = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    names = sorted(p.name for p in (ROOT / "config").glob("*.yaml"))
    assert len(names) >= 10 and {"paper_method.yaml", "paper_explicit.yaml"} <= set(names)
    for name in names:
        cfg = copy.deepcopy(base)
        update_config(cfg, yaml.safe_load((ROOT / "config" / name).read_text()))
        validate(cfg, str(schema))
        for group in cfg["sweep"]:
            run = {**defaults(RUN_PARAMETERS, workflow_only=True), **cfg["run"], **group.get("run", {})}
            flows = [chi_from_S(S, group["delta"]) for S in group.get("S", [])] + list(group.get("chi", []))
            for chi in flows:
                try:
                    RunConfig.from_dict({**run, "chi": chi})
                except ConfigError as exc:
                    raise AssertionError(f"config/{name}, sweep group {group}: {exc}") from None
    readme = (ROOT / "config" / "README.md").read_text()

    def keys(node):
        if isinstance(node, dict):
            for k, v in node.get("properties", {}).items():
                yield k
                yield from keys(v)
            for k, v in node.items():
                if k != "properties":
                    yield from keys(v)
        elif isinstance(node, list):
            for v in node:
                yield from keys(v)

    for key in set(keys(yaml.safe_load(schema.read_text()))) | set(keys(yaml.safe_load(params_schema.read_text()))):
        assert f"`{key}`" in readme, f"config/README.md does not document the key {key!r}"


def test_the_catalogs_test_config_is_the_tiny_config(tmp_path):
    """.test/config/config.yaml (what the Snakemake workflow catalog runs: `snakemake --directory .test`, the config
    read alone) is config/tiny.yaml (a link: one home), and both ways plan the same jobs with the same commands and
    run parameters as `--configfile config/tiny.yaml` merged over config/config.yaml."""
    link = ROOT / ".test" / "config" / "config.yaml"
    assert link.is_symlink() and link.resolve() == (ROOT / "config" / "tiny.yaml").resolve()
    wd = workflow_copy(tmp_path)
    shutil.copytree(ROOT / ".test" / "config", wd / ".test" / "config", symlinks=True)
    plans = []
    for args in (["--configfile", "config/tiny.yaml"], ["--directory", ".test"]):
        r = snakemake(wd, "all", "-n", "-p", *args)
        assert r.returncode == 0, r.stderr + r.stdout
        jobs = sorted((j["rule"], tuple(j["output"])) for j in planned_jobs(r.stdout))
        commands = sorted(re.findall(r"^Shell command: (.*?)(?=\n\n|\Z)", r.stdout, flags=re.M | re.S))
        plans.append((jobs, commands))
    assert plans[0][0] and plans[0] == plans[1]
    assert sum(c.count("\nscheme: projection\n") for c in plans[0][1]) == 2  # the tiny runs themselves


# --------------------------------------------------------------------------- paper scale
def test_paper_config_plans(tmp_path):
    """config/paper.yaml: the paper's seven cases at 256^3 and 512^3 with edge-h meshes, in the converged
    discretisation (the elongated two with the shape ALE), each run on CuPy with one GPU."""
    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "-n", "-p", "--configfile", "config/paper.yaml")
    assert r.returncode == 0, r.stderr + r.stdout
    jobs = planned_jobs(r.stdout)
    sims = sorted(j["wildcards"]["case_id"] for j in jobs if j["rule"] == "simulate")
    expected = [f"D0.116_S{S}_N{N}_Q{V}" for S in ("227", "553", "1106.5", "2224", "4448")
                for N, V in ((256, 38048), (512, 152192))]
    expected += [f"D0.997_S{S}_N{N}_Q{V}" for S in ("237", "947") for N, V in ((256, 38048), (512, 152192))]
    assert sims == sorted(expected)
    sim_blocks = r.stdout.split("rule simulate:")[1:]
    assert len(sim_blocks) == 14
    for block in sim_blocks:
        case = block.split("\n\n")[0]
        assert "gpu=1" in case
        for line in ("backend: cupy", "scheme: inextensible", "tension_space: harmonic", "coupling: sharp",
                     "kernel: bao6", "seed_spectrum: thermal", "dtype: float32", "L: 5.0", "tension_l_max: 78"):
            assert f"\n{line}\n" in case, (line, case[:200])
        ale = "shape" if "D0.997" in case.split("wildcards: case_id=")[1][:6] else "quality"
        assert f"\nmesh_ale: {ale}\n" in case


def test_paper_explicit_config_plans(tmp_path):
    """config/paper_explicit.yaml: the paper's method (explicit penalty, 4-point kernel coupling, mesh-noise seed) at
    512^3 with 26 070 vertices, one GPU per run."""
    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "-n", "-p", "--configfile", "config/paper_explicit.yaml")
    assert r.returncode == 0, r.stderr + r.stdout
    sims = sorted(j["wildcards"]["case_id"] for j in planned_jobs(r.stdout) if j["rule"] == "simulate")
    assert sims == sorted([f"D0.116_S{S}_N512_Q26070" for S in ("227", "553", "1106.5", "2224", "4448")]
                          + ["D0.997_S237_N512_Q26070", "D0.997_S947_N512_Q26070"])
    sim_blocks = r.stdout.split("rule simulate:")[1:]
    for block in sim_blocks:
        case = block.split("\n\n")[0]
        assert "gpu=1" in case
        for line in ("backend: cupy", "scheme: explicit", "coupling: kernel", "kernel: peskin4", "seed_spectrum: mesh",
                     "mesh_ale: none", "dtype: float64", "N: 512"):
            assert f"\n{line}\n" in case, (line, case[:200])
    assert r.stdout.count("\nL: 5.386\n") == 5 and r.stdout.count("\nL: 5.0\n") == 2


def test_paper_cpu_config_plans_on_top_of_the_default(tmp_path):
    """config/paper_cpu.yaml only re-sweeps: the paper's seven runs with config.yaml's discretisation, its ALE
    (mesh_ale quality) for the elongated two as well."""
    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "-n", "-p", "--configfile", "config/paper_cpu.yaml")
    assert r.returncode == 0, r.stderr + r.stdout
    sims = sorted(j["wildcards"]["case_id"] for j in planned_jobs(r.stdout) if j["rule"] == "simulate")
    assert sims == sorted([f"D0.116_S{S}_N128_Q9512" for S in ("227", "553", "1106.5", "2224", "4448")]
                          + ["D0.997_S237_N128_Q9512", "D0.997_S947_N128_Q9512"])
    assert "\ncoupling: sharp\n" in r.stdout and "\nkernel: bao6\n" in r.stdout
    assert r.stdout.count("\nmesh_ale: quality\n") == 7


def test_paper_converged_config_runs_each_point_at_its_own_resolution(tmp_path):
    """config/paper_converged.yaml: the paper's seven runs on top of config.yaml, S = 1106.5 and 4448 at 192^3 with
    their 21398-vertex mesh, the rest at 128^3, the elongated two with mesh_ale shape; the 192^3 runs start first."""
    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "-n", "-p", "--configfile", "config/paper_converged.yaml")
    assert r.returncode == 0, r.stderr + r.stdout
    jobs = planned_jobs(r.stdout)
    sims = {j["wildcards"]["case_id"]: j for j in jobs if j["rule"] == "simulate"}
    assert sorted(sims) == sorted([f"D0.116_S{S}_N128_Q9512" for S in ("227", "553", "2224")]
                                  + ["D0.116_S1106.5_N192_Q21398", "D0.116_S4448_N192_Q21398",
                                     "D0.997_S237_N128_Q9512", "D0.997_S947_N128_Q9512"])
    assert all(j.get("priority", 0) == (192 if "_N192_" in c else 128) for c, j in sims.items())
    assert r.stdout.count("\nmesh_ale: shape\n") == 2 and r.stdout.count("\nmesh_ale: quality\n") == 5
    assert sum(j["rule"] == "theory" for j in jobs) == 14 + 7  # the PA points of Fig. 4, and one per run
    # the paper's pattern claims: one report over the seven cases' microscope.nc, into the docs page's section
    (report,) = [j for j in jobs if j["rule"] == "morphology_report"]
    assert report["output"] == ["docs/validation_morphology.md"]
    assert sorted(re.findall(r"--case (\S+) results/runs/\1/microscope.nc results/runs/\1/spectra.nc", r.stdout)) \
        == sorted(sims)


def test_validation_config_plans(tmp_path):
    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "-n", "-p", "--configfile", "config/validation.yaml")
    assert r.returncode == 0, r.stderr + r.stdout
    jobs = planned_jobs(r.stdout)
    sims = sorted(j["wildcards"]["case_id"] for j in jobs if j["rule"] == "simulate")
    assert len(sims) == 14  # 5 + 2 fine, 5 coarse, 2 box
    assert any(j["rule"] == "validation_report" for j in jobs)
    assert "--box" in r.stdout and "--case" in r.stdout


def test_largest_grids_are_scheduled_first(tmp_path):
    """A sweep's longest jobs (the largest N) start first, and the meshes that gate them before any run: with
    arbitrary order, convergence.yaml could end with one 256^3 run alone on one of the two cores."""
    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "-n", "--configfile", "config/convergence.yaml")
    assert r.returncode == 0, r.stderr + r.stdout
    jobs = planned_jobs(r.stdout)
    sims = [j for j in jobs if j["rule"] == "simulate"]
    assert len(sims) == 22
    for j in sims:
        N = int(re.search(r"_N(\d+)_", j["wildcards"]["case_id"]).group(1))
        assert j.get("priority", 0) == N, j
    meshes = [j for j in jobs if j["rule"] == "mesh"]
    assert meshes and min(j.get("priority", 0) for j in meshes) > max(j["priority"] for j in sims)
    others = [j for j in jobs if j["rule"] not in ("simulate", "mesh")]
    assert all(j.get("priority", 0) == 0 for j in others)


#: the one lint the workflow keeps: its software is the project's pip extras (pip install -e ".[workflow]"), not a
#: conda environment per rule, which no CI here could build (no conda channel is reachable), so none is declared
NO_CONDA_LINT = "Specify a conda environment or container for each rule."


def test_lint_is_clean(tmp_path):
    import re

    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "--lint")
    out = r.stdout + r.stderr
    findings = re.findall(r"^\s+\* (.+?):$", out, flags=re.M)
    assert set(findings) <= {NO_CONDA_LINT}, out
    assert r.returncode == 0 or findings, out
    assert "Congratulations" in out or findings, out


# --------------------------------------------------------------------------- end to end
@pytest.mark.slow  # a run of the whole workflow; CI also runs it as its own stage (pytest -m slow; CI runs it)
def test_tiny_workflow_end_to_end(tmp_path):
    import xarray as xr

    from vesicle_core.data.catalog import read_catalog
    from vesicle_core.data.sweep import open_sweep

    wd = workflow_copy(tmp_path)
    r = snakemake(wd, "--cores", "2", "--configfile", "config/tiny.yaml", timeout=900)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    res = wd / "results"
    rows = read_catalog(res / "catalog.csv")
    kinds = sorted({row["kind"] for row in rows})
    assert kinds == ["fit", "mesh", "microscope", "spectra", "theory", "trajectory"]
    for row in rows:  # every catalog row points at a file that opens
        with xr.open_dataset(row["abspath"]) as ds:
            assert ds.sizes or ds.data_vars
    for nc in res.rglob("*.nc"):  # every netCDF output opens
        with xr.open_dataset(nc):
            pass
    pngs = list((res / "figures").rglob("*.png"))
    assert len(pngs) == 1 + 5 * 2
    for png in pngs:
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 2000
    for svg in (res / "figures").rglob("*.svg"):
        assert "<svg" in svg.read_text()
    for bench in (res / "benchmarks" / "simulate").glob("*.tsv"):
        assert bench.read_text().startswith("s\t")
    sweep = open_sweep(res / "catalog.csv")
    assert sweep.l_star.sel(S=553).size == 1
    r = snakemake(wd, "--report", "report.html", "--configfile", "config/tiny.yaml")
    assert r.returncode == 0 and (wd / "report.html").stat().st_size > 10_000, r.stderr[-2000:]
    r = snakemake(wd, "-n", "--configfile", "config/tiny.yaml")
    assert "Nothing to be done" in r.stdout + r.stderr
