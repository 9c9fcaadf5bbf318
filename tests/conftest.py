"""Fixtures shared by several test modules."""

import sys
import types

import numpy as np
import pytest


@pytest.fixture
def fake_cupy(monkeypatch):
    """A stand-in ``cupy``/``cupyx`` pair that answers with NumPy: the only check the CuPy-only branches get without a
    GPU (tests/solver/test_gpu_path.py says which). It implements the CuPy API the package calls (``get_array_module``,
    ``asarray``, ``asnumpy``, ``cuda.runtime.getDeviceCount``, ``fft``, ``cupyx.scatter_add``); everything else is
    NumPy's. Returns (cupy module, call counts of scatter_add, asnumpy and asarray)."""

    class _Cupy(types.ModuleType):
        def __getattr__(self, name):  # the rest of the API is NumPy's
            return getattr(np, name)

    cp = _Cupy("cupy")
    calls = {"scatter_add": 0, "asnumpy": 0, "asarray": 0}

    def scatter_add(out, idx, vals):
        calls["scatter_add"] += 1
        np.add.at(out, idx, vals)

    def asnumpy(a):
        calls["asnumpy"] += 1
        return np.array(a, copy=True)

    def asarray(a, dtype=None):
        calls["asarray"] += 1
        return np.asarray(a, dtype=dtype)

    cp.asnumpy = asnumpy
    cp.asarray = asarray
    cp.get_array_module = lambda *arrays: cp
    cp.cuda = types.SimpleNamespace(runtime=types.SimpleNamespace(getDeviceCount=lambda: 1))
    cp.fft = np.fft
    cp.ndarray = type("ndarray", (), {})  # no NumPy array is a CuPy array (xarray checks this type)
    cpx = types.ModuleType("cupyx")
    cpx.scatter_add = scatter_add
    monkeypatch.setitem(sys.modules, "cupy", cp)
    monkeypatch.setitem(sys.modules, "cupyx", cpx)
    return cp, calls


@pytest.fixture
def strict_cupy(monkeypatch):
    """The strict CuPy stand-in of tests/strict_cupy.py in place of ``cupy``/``cupyx``: device arrays of their own
    type that NumPy cannot read, and the count of host-device transfers (``cupy.transfers``). Returns the module."""
    from strict_cupy import install

    return install(monkeypatch)
