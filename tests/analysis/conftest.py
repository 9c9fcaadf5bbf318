"""Shapes shared by the analysis tests: a fine icosphere with its angles, and R (1 + eps Y_lm) on it."""

import numpy as np
import pytest

from vesicle_core.geometry import ylm as Yl
from vesicle_core.geometry.mesh import icosphere


@pytest.fixture(scope="module")
def ylm_sphere():
    """Level-5 icosphere (10,242 vertices) with the polar and azimuthal angles of its vertices."""
    v, f = icosphere(5)
    return v, f, np.arccos(v[:, 2]), np.arctan2(v[:, 1], v[:, 0])


@pytest.fixture(scope="module")
def perturbed(ylm_sphere):
    """perturbed(l, m, eps=0.02) -> (vertices, faces) of r = 1 + eps Re Y_lm / max|Re Y_lm| on ``ylm_sphere``."""

    def make(l, m, eps=0.02):
        v, f, th, ph = ylm_sphere
        y = Yl.ylm(l, th, ph)[l, l + m].real
        return v * (1.0 + eps * y / np.abs(y).max())[:, None], f

    return make
