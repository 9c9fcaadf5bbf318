"""The periodic Stokes solve (eqs. 21-23): the unit of cost of every scheme, one per tension-CG iteration.

A solve is three real FFTs forward, the spectral projection (times the sharp coupling's filter), three back
(vesicle_core.solver.stokes.StokesSolver.velocity). The bare FFT round trip on the same buffers is timed beside it:
the floor of the method, and the ratio solve / fft travels between machines better than either time.
"""

import numpy as np

from vesicle_core.model.parameters import SHARP_FLOOR
from vesicle_core.solver.backend import get_backend
from vesicle_core.solver.ibm import Grid
from vesicle_core.solver.kernels import sharpening_symbol
from vesicle_core.solver.stokes import StokesSolver

from .common import DTYPES, NS, L

# the coupling's kernel: the library's kernel coupling with the Peskin 4-point, the recommended sharp one with bao6
COUPLING_KERNEL = {"kernel": "peskin4", "sharp": "bao6"}


class StokesSolve:
    """One steady Stokes solve on an N^3 grid, per coupling (the sharp one multiplies by its filter) and dtype."""

    params = (NS, DTYPES, list(COUPLING_KERNEL))
    param_names = ["N", "dtype", "coupling"]

    def setup(self, N, dtype, coupling):
        be = get_backend("numpy", dtype=dtype, fft_workers=1)
        grid = Grid(N, L)
        filt = None if coupling == "kernel" else sharpening_symbol(N, COUPLING_KERNEL[coupling], SHARP_FLOOR)
        self.solver = StokesSolver(grid, be, force_filter=filt)
        self.f = be.empty(grid.field_shape)
        self.f[...] = np.random.default_rng(0).standard_normal(grid.field_shape)
        self.out = be.empty(grid.field_shape)
        self.solver.velocity(self.f, out=self.out)  # FFT plans and the symbols' caches: set-up, not the solve

    def time_velocity(self, N, dtype, coupling):
        self.solver.velocity(self.f, out=self.out)

    def peakmem_velocity(self, N, dtype, coupling):
        self.solver.velocity(self.f, out=self.out)


class BareFFT:
    """The floor: rfftn + irfftn of the 3-component N^3 field into persistent buffers (what a solve cannot beat)."""

    params = (NS, DTYPES)
    param_names = ["N", "dtype"]

    def setup(self, N, dtype):
        self.be = be = get_backend("numpy", dtype=dtype, fft_workers=1)
        self.grid = grid = Grid(N, L)
        self.f = be.empty(grid.field_shape)
        self.f[...] = np.random.default_rng(0).standard_normal(grid.field_shape)
        self.u = be.empty(grid.field_shape)
        self.chat = be.empty((3,) + grid.spectral_shape, be.complex_dtype)
        self.time_round_trip(N, dtype)

    def time_round_trip(self, N, dtype):
        self.be.rfftn(self.f, (1, 2, 3), out=self.chat)
        self.be.irfftn(self.chat, self.grid.shape, (1, 2, 3), out=self.u, overwrite_x=True, norm="forward")
