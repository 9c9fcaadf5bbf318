"""The mesh-bias measure of issue 7 detects wrinkles pinned to mesh defects and ignores unbiased ones."""

import numpy as np
import pytest

from vesicle_core.analysis import mesh_bias as MB
from vesicle_core.geometry import mesh as M

SPHERE = (np.zeros(3), np.ones(3), np.eye(3))


def _bumpy(v, centres, amp=0.01, width=0.15):
    d = v / np.linalg.norm(v, axis=1, keepdims=True)
    r = 1 + amp * np.exp(-(1 - d @ centres.T) / width**2).sum(axis=1)
    return v * r[:, None]


def test_wrinkles_at_fivefold_vertices_are_flagged():
    v, f = M.icosphere(4)
    b = MB.mesh_bias(_bumpy(v, MB.icosahedron_directions()), f, SPHERE)
    assert b["n_defects"] == 12
    assert b["defect_amplitude_ratio"] > 3 and b["icosahedral_amplitude_ratio"] > 3


def test_unbiased_pattern_scores_near_one():
    v, f = M.icosphere(4)
    rng = np.random.default_rng(0)
    centres = rng.standard_normal((300, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    ratios = MB.mesh_bias(_bumpy(v, centres, width=0.1), f, SPHERE)
    assert 0.3 < ratios["defect_amplitude_ratio"] < 2.0


def test_power_ratio_of_flat_spectrum_is_one():
    D = np.ones(20)
    v, f = M.icosphere(2)
    bias = MB.mesh_bias(_bumpy(v, MB.icosahedron_directions()), f, SPHERE, D)
    assert bias["icosahedral_power_ratio"] == pytest.approx(1.0)


def test_quasiuniform_defects_are_many():
    m = M.make_vesicle("quasiuniform", n_vertices=1000, axes=(1, 1, 1))
    b = MB.mesh_bias(m.vertices * 1.0001, m.faces, SPHERE)
    assert b["n_defects"] > 12
