"""The workflow beyond one machine: the SLURM profile for CPU nodes asks for no GPU and runs NumPy, the GPU profiles
run CuPy with one GPU per run, and (slow) the tiny workflow runs through a real SLURM cluster
(`.ci/slurm-single-node.sh start`) with the CPU profile, with the spectra of a local run. Every test works in a
temporary copy of Snakefile, workflow/ and config/."""

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from snakemake_runner import run_snakemake

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
PROFILES = ROOT / "workflow" / "profiles"
SLURM_BINARIES = ("sbatch", "srun", "squeue", "sinfo", "scontrol")


def _env():
    env = dict(os.environ)
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    env.setdefault("MPLBACKEND", "Agg")
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    env.setdefault("PYVISTA_OFF_SCREEN", "true")
    return env


def _workflow_copy(dst):
    dst.mkdir(parents=True)
    shutil.copy(ROOT / "Snakefile", dst / "Snakefile")
    shutil.copytree(ROOT / "workflow", dst / "workflow")
    shutil.copytree(ROOT / "config", dst / "config")
    return dst


def _snakemake(wd, *args, timeout=300):
    return run_snakemake(wd, args, _env(), timeout=timeout)


def _simulate_blocks(text):
    """The dry run's `rule simulate:` blocks (resources line and the run.yaml of the shell command)."""
    return [b.split("\n\n")[0] for b in text.split("rule simulate:")[1:]]


def _gpu_values(node):
    """Every value of a `gpu`, `gpus` or `gres` key anywhere in a profile, and every string that names a GPU
    request to sbatch (slurm_extra)."""
    if isinstance(node, dict):
        for k, v in node.items():
            if k in ("gpu", "gpus", "gres", "gpus_per_task", "tasks_per_gpu"):
                yield k, v
            elif isinstance(v, str) and re.search(r"--(gpus|gres)", v):
                yield k, v
            else:
                yield from _gpu_values(v)


# --------------------------------------------------------------------------- profiles
def test_cpu_cluster_profile_requests_no_gpu(tmp_path):
    """workflow/profiles/slurm: the SLURM executor, no GPU in any resource, NumPy runs; a dry run of the GPU-scale
    config (resources.simulate.gpu = 1, backend cupy) through it plans every run with gpu=0 on NumPy."""
    prof = yaml.safe_load((PROFILES / "slurm" / "config.yaml").read_text())
    assert prof["executor"] == "slurm"
    gpu = list(_gpu_values(prof))
    assert gpu == [("gpu", 0)], gpu  # set-resources: simulate: gpu: 0, which overrides the config's
    assert "run={backend: numpy}" in prof["config"]
    wd = _workflow_copy(tmp_path / "wf")
    # --executor local: the plan is the profile's (resources, config), without the SLURM plugin installed
    r = _snakemake(wd, "-n", "-p", "--workflow-profile", "workflow/profiles/slurm", "--executor", "local",
                   "--configfile", "config/paper.yaml")
    assert r.returncode == 0, r.stderr + r.stdout
    blocks = _simulate_blocks(r.stdout)
    assert len(blocks) == 14
    for block in blocks:
        resources = next(line for line in block.splitlines() if line.strip().startswith("resources:"))
        assert "gpu=0" in resources and "slurm_partition=cpu" in resources, resources
        assert "\nbackend: numpy\n" in block


@pytest.mark.parametrize("profile", ["gpu", "slurm-gpu"])
def test_gpu_profiles_run_cupy_on_one_gpu(tmp_path, profile):
    """workflow/profiles/gpu (one workstation) and slurm-gpu (a cluster): every run of a CPU config (the default,
    backend numpy, resources.simulate.gpu = 0) is planned on CuPy with one GPU, and only the runs take a GPU."""
    prof = yaml.safe_load((PROFILES / profile / "config.yaml").read_text())
    assert "run={backend: cupy}" in prof["config"]
    wd = _workflow_copy(tmp_path / "wf")
    r = _snakemake(wd, "-n", "-p", "--workflow-profile", f"workflow/profiles/{profile}", "--executor", "local",
                   "--configfile", "config/config.yaml")
    assert r.returncode == 0, r.stderr + r.stdout
    blocks = _simulate_blocks(r.stdout)
    assert len(blocks) == 3
    for block in blocks:
        assert "gpu=1" in block and "\nbackend: cupy\n" in block, block[:300]
    assert r.stdout.count("gpu=1") == 3  # meshes, spectra, PA, figures: no GPU


# --------------------------------------------------------------------------- a real SLURM cluster
def _slurm_missing():
    """Why the SLURM check cannot run here, or None."""
    missing = [b for b in SLURM_BINARIES if shutil.which(b) is None]
    if missing:
        return f"SLURM binaries not found ({', '.join(missing)}): apt-get install -y slurm-wlm munge"
    try:
        import snakemake_executor_plugin_slurm  # noqa: F401
    except ImportError:
        return "snakemake-executor-plugin-slurm is not installed: pip install -e '.[cluster]'"
    r = subprocess.run(["sinfo", "-h", "-o", "%T"], capture_output=True, text=True, timeout=30)
    if r.returncode != 0 or not any(s.startswith(("idle", "mix", "alloc")) for s in r.stdout.split()):
        return (f"no SLURM cluster answers (sinfo: {(r.stderr or r.stdout).strip() or 'no node up'}); "
                "start one with .ci/slurm-single-node.sh start")
    return None


def _submitted(text):
    """{SLURM job id: rule} of the jobs the executor submitted (its log lines)."""
    pat = r"submitted with SLURM jobid (\d+) \(log: \S*/slurm_logs/rule_(\w+)/"
    return {int(j): rule for j, rule in re.findall(pat, text)}


@pytest.mark.slow
def test_tiny_workflow_through_slurm_equals_local_run(tmp_path):
    """`snakemake --cores 2 all --configfile config/tiny.yaml` through `--executor slurm` with the CPU profile: every
    job is a SLURM job, none asks SLURM for a GPU, and the spectra equal a local run's (l_* and Delta_l)."""
    reason = _slurm_missing()
    if reason and os.environ.get("VESICLE_REQUIRE_SLURM") == "1":  # .ci/run started a cluster: missing is a failure
        pytest.fail(reason)
    if reason:
        pytest.skip(reason)
    import xarray as xr

    cluster = _workflow_copy(tmp_path / "slurm")
    t0 = time.perf_counter()
    # job states through squeue: the test cluster has no accounting database for sacct (.ci/slurm-single-node.sh)
    r = _snakemake(cluster, "--cores", "2", "all", "--configfile", "config/tiny.yaml",
                   "--workflow-profile", "workflow/profiles/slurm", "--slurm-status-command", "squeue",
                   "--slurm-init-seconds-before-status-checks", "2", "--retries", "0", timeout=1800)
    wall = time.perf_counter() - t0
    assert r.returncode == 0, r.stderr[-6000:]
    jobs = _submitted(r.stderr + r.stdout)
    rules = sorted(set(jobs.values()))
    assert {"mesh", "simulate", "analyze", "theory", "catalog"} <= set(rules), rules
    print(f"tiny workflow through SLURM: {len(jobs)} jobs, {wall:.0f} s")
    for job, rule in jobs.items():
        if rule == "simulate":
            show = subprocess.run(["scontrol", "show", "job", str(job)], capture_output=True, text=True,
                                  timeout=30).stdout
            fields = dict(tok.split("=", 1) for tok in show.split() if "=" in tok)
            assert fields.get("JobState") == "COMPLETED", show
            # no --gpus, --gres or TRES gpu (the test cluster has no GPU gres, so sbatch would also refuse one)
            gpu = {k: v for k, v in fields.items() if k.startswith(("Tres", "TRES", "Gres", "CpusPerTres",
                                                                     "MemPerTres")) and "gpu" in v.lower()}
            assert not gpu, gpu

    local = _workflow_copy(tmp_path / "local")
    cases = sorted(p.parent.name for p in (cluster / "results" / "runs").glob("*/spectra.nc"))
    assert len(cases) == 2, cases
    targets = [f"results/runs/{c}/spectra.nc" for c in cases]
    r = _snakemake(local, "--cores", "2", *targets, "--configfile", "config/tiny.yaml", timeout=900)
    assert r.returncode == 0, r.stderr[-6000:]
    for case in cases:
        with xr.open_dataset(cluster / "results/runs" / case / "spectra.nc") as a, \
                xr.open_dataset(local / "results/runs" / case / "spectra.nc") as b:
            assert np.isfinite(float(a["l_star"])), case
            np.testing.assert_allclose(float(a["l_star"]), float(b["l_star"]), rtol=1e-12, err_msg=case)
            np.testing.assert_array_equal(a["l"].values, b["l"].values)
            np.testing.assert_allclose(a["Delta_l"].values, b["Delta_l"].values, rtol=1e-12, atol=0,
                                       equal_nan=True, err_msg=case)
