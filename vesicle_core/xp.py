"""The one array-module switch: NumPy, or CuPy for arrays that live on a GPU.

Functions that take arrays ask :func:`array_module` which module to compute with, and :func:`to_numpy` brings a
result back to the host. CuPy is looked up in ``sys.modules``, never imported here: a CuPy array can only exist
once CuPy has been imported (by :mod:`vesicle_core.solver.backend`), so the lookup answers the same as an import
would, costs nothing on a CPU-only machine, and lets the tests' CuPy stand-in take CuPy's place.
"""

from __future__ import annotations

import sys

import numpy as np


def array_module(*arrays):
    """``numpy``, or ``cupy`` when any of ``arrays`` is a CuPy array (``cupy.get_array_module``)."""
    cupy = sys.modules.get("cupy")
    if cupy is None:
        return np
    return cupy.get_array_module(*arrays)


def to_numpy(a) -> np.ndarray:
    """``a`` as a host NumPy array: a copy from the device for CuPy arrays (``.get()``), no copy otherwise."""
    return np.asarray(a.get() if hasattr(a, "get") else a)


def to_float(a) -> float:
    """A one-element array (a reduction's result) as a Python float. On a GPU this is a synchronising read of one
    number, written out so that every such read is visible: CuPy's own ``float(x)`` does the same copy implicitly,
    and the tests' strict CuPy stand-in refuses it (tests/strict_cupy.py) and counts this one."""
    return float(to_numpy(a))
