"""The core (numpy, scipy, xarray, netCDF4, PyYAML, tqdm) works without the extras: every module imports, the FFTs
fall back to scipy.fft and the Stokes pass to NumPy, and a feature that needs an extra says which one."""

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from unit_run import UNIT_RUN

from vesicle_core.errors import MissingDependency, VesicleError, require

ROOT = Path(__file__).resolve().parents[1]
#: the packages of the extras (workflow, viz, fast, gpu, esm, microscopy), blocked in the subprocess below
OPTIONAL = ("snakemake", "jsonschema", "jinja2", "pyarrow", "matplotlib", "pyvista", "vtk", "numba", "pyfftw", "cupy",
            "intake", "intake_esm", "trimesh", "skimage")

CORE_ONLY = textwrap.dedent(f"""
    import importlib, pkgutil, sys

    class Block:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {OPTIONAL!r}:
                raise ImportError(f"blocked: {{name}}")
            return None

    sys.meta_path.insert(0, Block())
    import numpy as np
    import vesicle_core
    for m in pkgutil.walk_packages(vesicle_core.__path__, "vesicle_core."):
        if not m.name.endswith(".__main__"):  # that one runs the command
            importlib.import_module(m.name)
    from vesicle_core.geometry import mesh
    from vesicle_core.solver import backend, stokes
    from vesicle_core.model.run_config import RunConfig
    from vesicle_core.solver.simulate import run
    assert backend.get_backend().fft_library == "scipy"
    assert stokes._compiled_steady_pass() is None
    m = mesh.make_vesicle("icosphere", level=1)
    cfg = RunConfig(**{{**{UNIT_RUN!r}, **dict(chi=20.0, N=16, stretch=0.05, t_end=0.02, output_every=0.01,
                                            Lambda=2e4, K_volume=1e6)}})
    path = run(m, cfg, sys.argv[1], progress=False)
    from vesicle_core.data.catalog import write_catalog
    write_catalog([path], sys.argv[1] + "/catalog.csv")
    from vesicle_core.viz import plots
    try:
        plots._mpl()
    except vesicle_core.errors.MissingDependency as exc:
        assert "[viz]" in str(exc), exc
    else:
        raise AssertionError("matplotlib was not blocked")
    print("core ok")
""")


def test_core_runs_without_the_extras(tmp_path):
    r = subprocess.run([sys.executable, "-c", CORE_ONLY, str(tmp_path)], capture_output=True, text=True, cwd=ROOT,
                       timeout=300, env={"OPENBLAS_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0 and "core ok" in r.stdout, r.stdout + r.stderr
    assert (tmp_path / "trajectory.nc").exists()
    assert (tmp_path / "catalog.csv").exists() and not (tmp_path / "catalog.parquet").exists()


def test_require_names_the_extra():
    assert require("math", "viz", "x").sqrt(4.0) == 2.0
    with pytest.raises(MissingDependency, match=r"pip install 'vesicle-wrinkling\[viz\]'") as exc:
        require("no_such_module_anywhere", "viz", "plotting")
    assert isinstance(exc.value, VesicleError) and isinstance(exc.value, ImportError)
    assert "plotting needs no_such_module_anywhere" in str(exc.value)


def test_render_engine_pyvista_without_pyvista_says_so(monkeypatch):
    from vesicle_core.viz import render

    monkeypatch.setitem(sys.modules, "pyvista", None)  # import pyvista now raises ImportError
    with pytest.raises(MissingDependency, match=r"\[viz\]"):
        render.select_engine("pyvista")
