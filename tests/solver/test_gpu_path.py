"""Every CuPy-only branch, run on the CPU: a stand-in ``cupy``/``cupyx`` pair that answers with NumPy.

No GPU has run this code. The stand-in here answers with NumPy arrays, so it cannot see an implicit conversion; the
strict stand-in (tests/strict_cupy.py, tests/solver/test_strict_gpu_path.py) can. This one (the ``fake_cupy``
fixture of tests/conftest.py) implements the CuPy API the package calls (``get_array_module``, ``asarray``,
``asnumpy``, ``cuda.runtime.getDeviceCount``, ``fft``, ``cupyx.scatter_add``); everything else is NumPy's. A run
on ``backend: cupy`` then takes the GPU branches
(``Backend.is_gpu``: asnumpy, scatter_add, the xp.fft path, the non-interleaved spectral layout, the generic
gather in ibm.interpolate) and must give the NumPy run's numbers to FFT round-off.
"""

import numpy as np
import pytest
import xarray as xr
from unit_run import unit_run

from vesicle_core.geometry import mesh as M
from vesicle_core.solver import backend as backend_module


def test_cupy_backend_is_selected_and_takes_gpu_branches(fake_cupy):
    cp, calls = fake_cupy
    assert backend_module.cupy_available()
    be = backend_module.get_backend("cupy")
    assert be.name == "cupy" and be.xp is cp and be.is_gpu and be.uses_xp_fft
    assert backend_module.get_backend("auto").name == "cupy"
    out = be.scatter_add(np.zeros(4), np.array([0, 0, 3]), np.array([1.0, 2.0, 5.0]))
    np.testing.assert_array_equal(out, [3.0, 0.0, 0.0, 5.0])
    assert calls["scatter_add"] == 1
    assert be.asnumpy(np.ones(2)).sum() == 2 and calls["asnumpy"] == 1


@pytest.mark.parametrize("scheme,coupling", [("projection", "kernel"), ("inextensible", "kernel"),
                                             ("projection", "sharp")])
def test_a_run_on_the_gpu_path_matches_numpy(fake_cupy, tmp_path, scheme, coupling):
    from vesicle_core.solver.simulate import run

    _, calls = fake_cupy
    m = M.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    # the sharp coupling moves mesh-scale modes faster (less smoothing), so its stable step is shorter
    base = dict(chi=20.0, N=16, stretch=0.1, t_end=0.05, output_every=0.05, scheme=scheme,
                dt=2.5e-4 if coupling == "kernel" else 5e-5, coupling=coupling)
    if scheme == "inextensible":  # a CG converged to round-off, so that only round-off can differ
        base.update(cg_tol=1e-10, cg_maxiter=2000)
    out = {}
    for name in ("numpy", "cupy"):
        with xr.open_dataset(run(m, unit_run(**base, backend=name), tmp_path / name, progress=False)) as ds:
            out[name] = ds.load()
    assert calls["scatter_add"] > 0 and calls["asnumpy"] > 0  # the GPU branches ran
    a, b = out["numpy"], out["cupy"]
    assert b.attrs["backend"] == "cupy"
    for v in ("node_x", "node_y", "node_z"):
        # pocketFFT/pyFFTW against numpy.fft, and another summation order in the scatter: round-off only
        np.testing.assert_allclose(b[v].values, a[v].values, rtol=0, atol=1e-10)
    np.testing.assert_allclose(b["tension"].values, a["tension"].values, rtol=1e-6)
