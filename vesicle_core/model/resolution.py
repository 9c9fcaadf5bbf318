"""The kernels by name, and how far each coupling resolves a membrane mode on a grid (measured laws).

These are facts about the discretisation that the solver (its step estimate), the analysis (the PA on the grid,
eqs. 11-12 with damped rates) and the parameters (the allowed ``kernel`` values) all use, so they live below
all three. The kernels themselves are in :mod:`vesicle_core.solver.kernels`.
"""

from __future__ import annotations

import numpy as np

KERNELS = {"peskin4": 4, "roma3": 3, "bao6": 6}  # name -> support width (nodes per axis)
#: the paper's kernel, eq. (27): the default of every function here and of the run parameter `kernel`
DEFAULT_KERNEL = "peskin4"

# How far each kernel resolves a membrane mode: the IBM's relaxation rate of a sphere mode Y_l0 over the
# linear theory follows exp(-(l h / a)^2) with this a (fitted over l h = 0.23-1.56 at N = 32 and 64, edge ~ 2h,
# clean interface; benchmarks/bench_resolution.py). A wider kernel smears the membrane more.
RESOLUTION_LENGTH = {"peskin4": 1.04, "roma3": 1.35, "bao6": 0.90}


# The same for the sharp coupling at its default floor (parameters.SHARP_FLOOR) and a mesh edge of ~h: the ratio
# stays within ~1% of 1 and then falls faster, exp(-(l h / a)^p), (a, p) fitted over the ratios below 0.99 at
# N = 64-192 (benchmarks/bench_resolution.py, docs/explanation/resolution.md, "Sharpened coupling").
SHARP_RESOLUTION = {"peskin4": (2.38, 3.88), "roma3": (2.47, 7.20), "bao6": (2.36, 3.29)}


def mode_damping(l, h, kernel=DEFAULT_KERNEL, coupling="kernel"):
    """IBM / theory rate ratio of a membrane mode l on a grid of spacing h (in R), the fits above."""
    lh = np.asarray(l, dtype=float) * h
    if coupling == "sharp":
        a, p = SHARP_RESOLUTION[kernel]
        return np.exp(-((lh / a) ** p))
    if coupling != "kernel":
        raise ValueError(f"coupling must be 'kernel' or 'sharp', got {coupling!r}")
    return np.exp(-((lh / RESOLUTION_LENGTH[kernel]) ** 2))
