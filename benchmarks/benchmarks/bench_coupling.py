"""Spreading and interpolation, the IBM's coupling between the membrane and the grid (eqs. 16, 26-29).

prepare: each vertex's kernel stencil (indices and weights, eqs. 26-27), once per step; spread: the vertex forces
onto the grid (28); interpolate: the grid velocity back to the vertices (16, 29). Their cost is set by the number
of vertices times the stencil (4^3 = 64 nodes for the Peskin 4-point kernel of the library's ``coupling: kernel``,
6^3 = 216 for bao6, which the recommended ``coupling: sharp`` uses). The sharp coupling's own extra work, its
filter, is a multiply in the spectral solve: bench_stokes.StokesSolve times it.
"""

import numpy as np

from vesicle_core.solver.backend import get_backend
from vesicle_core.solver.ibm import Coupler, Grid

from .common import DTYPES, NS, L, mesh_for, perturbed

KERNELS = ["peskin4", "bao6"]


class SpreadInterpolate:
    """prepare, spread and interpolate on an N^3 grid with the N-matched mesh (596 / 2379 vertices), per kernel."""

    params = (NS, DTYPES, KERNELS)
    param_names = ["N", "dtype", "kernel"]

    def setup(self, N, dtype, kernel):
        be = get_backend("numpy", dtype=dtype, fft_workers=1)
        grid = Grid(N, L)
        m = mesh_for(N)
        rng = np.random.default_rng(1)
        self.X = perturbed(m.vertices)
        self.F = rng.standard_normal(self.X.shape)
        self.cp = Coupler(grid, be, kernel=kernel)
        self.u = be.empty(grid.field_shape)
        self.u[...] = rng.standard_normal(grid.field_shape)
        self.cp.prepare(self.X)  # the persistent stencil and work buffers, as after a run's first step
        self.cp.spread(self.F)
        self.cp.interpolate(self.u)

    def time_prepare(self, N, dtype, kernel):
        self.cp.prepare(self.X)

    def time_spread(self, N, dtype, kernel):
        self.cp.spread(self.F)

    def time_interpolate(self, N, dtype, kernel):
        self.cp.interpolate(self.u)
