"""Shared set-up of the asv suite: the grids and meshes every benchmark class is parametrised over.

The two grids are N = 32 and 64 in the default box L = 5 R. Each gets the mesh the recommended method pairs with it:
a quasi-uniform mesh whose mean edge is one grid spacing h (the sharp coupling's rule; config/config.yaml pairs
N = 128 with 9512 vertices the same way), stretched to the paper's excess area Delta = 0.116. That is 596 vertices at
N = 32 and 2379 at N = 64, so that N = 64 / N = 32 is 8x the grid points and 4x the vertices.
"""

from __future__ import annotations

from functools import cache

import numpy as np

L = 5.0  # box edge [R], the default job's
DELTA = 0.116  # the paper's quasi-spherical excess area
NS = [32, 64]
DTYPES = ["float32", "float64"]  # the `dtype` run parameter: precision of the grid fields and FFTs


@cache
def mesh_for(N: int):
    """The quasi-uniform vesicle mesh with mean edge ~ h = L / N at Delta = 0.116 (vesicle_core.geometry.mesh)."""
    from vesicle_core.geometry import mesh as M

    return M.make_vesicle("quasiuniform", n_vertices=M.vertices_for_edge(L / N), target_delta=DELTA)


def perturbed(vertices, scale=1e-3, seed=0):
    """The mesh's vertices moved by ``scale`` R at random: a shape off the reference, so forces are not zero."""
    rng = np.random.default_rng(seed)
    return vertices + scale * rng.standard_normal(vertices.shape)
