"""Eulerian grid and the Lagrangian <-> Eulerian coupling of the immersed boundary method.

* :class:`Grid`: the periodic box [-L/2, L/2)^3 with N nodes per axis, h = L / N (the Delta x of
  Sec. IV B), node m at -L/2 + m h.
* :func:`prepare`: once per time step, the 4 x 4 x 4 = 64 grid nodes each Lagrangian point touches
  (flattened, periodic) and their tensor-product weights phi(r_1/h) phi(r_2/h) phi(r_3/h) of
  eqs. (26)-(27). Spreading and interpolation share this :class:`Stencil`, so they are exact adjoints:
  <S F, u> h^3 = <F, J u>.
* :func:`spread`: force density of eq. (28), f_m = sum_k F_k delta_h(x_m - X_k) (weights / h^3).
* :func:`interpolate`: U_k = sum_m u_m delta_h(x_m - X_k) h^3 (eqs. 16 and 29), i.e. the plain
  weighted sum (the weights of a point sum to 1, so constants are reproduced exactly; the first
  moment of phi vanishes, so linear fields are too).
* :class:`Spreader`: spreading into a persistent grid buffer that is cleared sparsely (only the nodes
  touched by the previous call), which avoids allocating/zeroing 3 N^3 values every step.
* :class:`Coupler`: per-run workspace bundling prepare / spread / interpolate with reused buffers
  (the form a time stepper should use).

Everything is vectorised over points (no Python loop over points; one call per force component).
Cost on the 2-core reference VM (timed inside a full step, i.e. with caches evicted by the FFT),
N = 128: 2562 points: prepare ~1.5 ms (about 1 ms of it kernels.stencil), spread ~2 ms,
interpolate ~1 ms; 10242 points: ~6, ~8, ~4 ms; against 60-70 ms for the FFT round trip.
Fresh (M, 64) arrays every step cost page faults comparable to the arithmetic, hence the
``out=`` / ``work=`` arguments and the Coupler.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from ..model.resolution import DEFAULT_KERNEL, KERNELS
from .kernels import stencil as _kernel_stencil

STENCIL_WIDTH = 4  # Peskin's 4-point kernel, eq. (27): the default
STENCIL_SIZE = STENCIL_WIDTH**3


@dataclass(frozen=True)
class Grid:
    """Periodic cube [-L/2, L/2)^3 with N nodes per axis (N even, >= 8), spacing h = L / N."""

    N: int
    L: float

    def __post_init__(self):
        n = check_range("N", self.N, 8, None, integer=True)
        if n % 2:
            raise ConfigError(f"N must be an even integer >= 8, got {self.N!r}")
        L = float(check_range("L", self.L, 0.0, None, lo_open=True))
        object.__setattr__(self, "N", int(n))
        object.__setattr__(self, "L", L)

    @property
    def h(self) -> float:
        """Grid spacing Delta x = L / N."""
        return self.L / self.N

    @property
    def origin(self) -> float:
        """Coordinate of node 0 on every axis (-L/2)."""
        return -0.5 * self.L

    @property
    def shape(self) -> tuple:
        return (self.N, self.N, self.N)

    @property
    def field_shape(self) -> tuple:
        """Shape of a vector field on the grid: (3, N, N, N)."""
        return (3, self.N, self.N, self.N)

    @property
    def spectral_shape(self) -> tuple:
        """Shape of one component after a real FFT over the 3 axes: (N, N, N//2 + 1)."""
        return (self.N, self.N, self.N // 2 + 1)

    @property
    def cell_volume(self) -> float:
        return self.h**3

    def axis_coords(self):
        """Node coordinates -L/2 + m h, m = 0..N-1 (NumPy, float64)."""
        return self.origin + self.h * np.arange(self.N)


@dataclass
class Stencil:
    """Per-step coupling data shared by :func:`spread` and :func:`interpolate`.

    idx : int array (M, 64)  flat index i N^2 + j N + k of the touched nodes (periodic); the 64
                             columns run over the offsets (c, a, b) along (z, x, y).
    w   : array (M, 64)      matching dimensionless weights phi phi phi (each row sums to 1).
    """

    idx: object
    w: object
    N: int

    @property
    def n_points(self) -> int:
        return int(self.idx.shape[0])


def prepare(X, grid: Grid, backend, out: Stencil | None = None, kernel: str = DEFAULT_KERNEL) -> Stencil:
    """Stencil of the 4-point kernel (26)-(27) around the Lagrangian points X (M, 3).

    Computed once per time step and shared by spreading (28) and interpolation (29).
    Points outside the box are wrapped periodically. ``out``: a Stencil of the same size whose
    arrays are overwritten in place (saves page-faulting two fresh (M, 64) arrays every step,
    which on the reference VM cost about as much as computing them).
    """
    xp = backend.xp
    X = xp.asarray(X, dtype=xp.float64)
    if X.ndim != 2 or X.shape[1] != 3:
        raise ConfigError(f"X must have shape (M, 3), got {tuple(X.shape)}")
    N = grid.N
    M = X.shape[0]
    if kernel not in KERNELS:
        raise ConfigError(f"kernel must be one of {tuple(KERNELS)}, got {kernel!r}")
    width = KERNELS[kernel]
    size = width**3
    idx, w = _kernel_stencil(X, grid.h, N, grid.origin, xp=xp, kernel=kernel)  # (M, 3, width) each
    dt = np.dtype(backend.dtype)
    if (out is not None and tuple(out.idx.shape) == (M, size) and out.idx.dtype == xp.intp
            and out.w.dtype == dt and out.idx.flags.c_contiguous and out.w.flags.c_contiguous):
        flat, wt = out.idx, out.w
        out.N = N
    else:
        out = None
        flat = xp.empty((M, size), dtype=xp.intp)
        wt = xp.empty((M, size), dtype=dt)
    # Column order within a row is (c, a, b) with a, b, c the offsets along x, y, z: any fixed
    # order of the 64 entries works (spread and interpolate only pair idx with w), and putting
    # the 16 (a, b) pairs innermost gives NumPy 16-long inner loops instead of 4-long ones
    # (~3x faster than the (a, b, c) broadcast).
    ix = idx[:, 0, :] * (N * N)
    iy = idx[:, 1, :] * N
    w2 = width * width
    sab = (ix[:, :, None] + iy[:, None, :]).reshape(M, 1, w2)
    xp.add(sab, idx[:, 2, :, None], out=flat.reshape(M, width, w2))
    pab = (w[:, 0, :, None] * w[:, 1, None, :]).reshape(M, 1, w2).astype(dt, copy=False)
    xp.multiply(pab, w[:, 2, :, None].astype(dt, copy=False), out=wt.reshape(M, width, w2))
    return out if out is not None else Stencil(flat, wt, N)


def _check_forces(F, stencil, backend):
    F = backend.xp.asarray(F)
    if F.shape != (stencil.n_points, 3):
        raise ConfigError(f"F must have shape ({stencil.n_points}, 3), got {tuple(F.shape)}")
    return F


def _check_field(a, grid, name):
    if tuple(a.shape) != grid.field_shape:
        raise ConfigError(f"{name} must have shape {grid.field_shape}, got {tuple(a.shape)}")


def _work(work, shape, dtype, xp):
    """Reuse ``work`` when it has the right shape/dtype, else allocate."""
    if work is not None and tuple(work.shape) == tuple(shape) and work.dtype == dtype:
        return work
    return xp.empty(shape, dtype=dtype)


def _scatter_loop(out, idx, w, scale):
    """out[idx[k, j]] += w[k, j] * scale[k] for every k, j in that order: the additions of ``np.add.at`` on the
    flattened product, in the same order and precision, so the grid is the same bit for bit (tested). Compiled by
    numba (:func:`_compiled_scatter`); far too slow as plain Python."""
    for k in range(idx.shape[0]):
        s = scale[k]
        for j in range(idx.shape[1]):
            out[idx[k, j]] += w[k, j] * s


def _zero_loop(out, idx):
    """out[idx[k, j]] = 0 for every k, j: the Spreader's sparse clear. Compiled with :func:`_compiled_scatter`."""
    for k in range(idx.shape[0]):
        for j in range(idx.shape[1]):
            out[idx[k, j]] = 0


@functools.cache
def _compiled_zero():
    """:func:`_zero_loop` compiled by numba, or None without numba (the fancy-index assignment took ~15 ms of the
    36 ms spread above)."""
    return _njit(_zero_loop, (np.zeros(4), np.zeros((1, 2), dtype=np.intp)))


def _njit(fn, example_args):
    """fn compiled by numba (cached on disk where it can be), or None when numba is not installed."""
    try:
        import numba
    except ImportError:
        return None
    kernel = numba.njit(cache=True, nogil=True, boundscheck=False)(fn)
    try:  # compile now: a read-only package folder and user cache make caching raise here
        kernel(*example_args)
    except RuntimeError:
        kernel = numba.njit(cache=False, nogil=True, boundscheck=False)(fn)
    return kernel


@functools.cache
def _compiled_scatter():
    """:func:`_scatter_loop` compiled by numba (cached on disk), or None without numba. At N = 128 with 10242
    points np.add.at took 20 ms of a 36 ms spread (two other runs on the 2-core machine; ~12% of a Stokes solve)."""
    return _njit(_scatter_loop, (np.zeros(4), np.zeros((1, 2), dtype=np.intp), np.zeros((1, 2)), np.zeros(1)))


def _scatter(F, stencil, grid, backend, out, work=None):
    """out[c] += sum_k F_kc w_k / h^3 at the stencil nodes (out contiguous). Returns (out, work)."""
    xp = backend.xp
    inv_h3 = 1.0 / grid.h**3
    dt = out.dtype
    compiled = None if backend.is_gpu else _compiled_scatter()
    if compiled is not None and stencil.w.dtype == dt:
        for c in range(3):
            compiled(out[c].reshape(-1), stencil.idx, stencil.w, (F[:, c] * inv_h3).astype(dt, copy=False))
        return out, work
    vals = _work(work, stencil.w.shape, dt, xp)
    idx = stencil.idx.reshape(-1)
    for c in range(3):
        scale = (F[:, c] * inv_h3).astype(dt, copy=False)
        xp.multiply(stencil.w, scale[:, None], out=vals)
        backend.scatter_add(out[c].reshape(-1), idx, vals.reshape(-1))
    return out, vals


def spread(F, stencil: Stencil, grid: Grid, backend, out=None):
    """Force density on the grid, eq. (28): f_m = sum_k F_k delta_h(x_m - X_k).

    F : (M, 3) Lagrangian forces. Returns f of shape (3, N, N, N), dtype backend.dtype, with
    sum_m f_m h^3 = sum_k F_k. ``out`` (contiguous, shape (3, N, N, N)) is zeroed and filled;
    for repeated use prefer :class:`Spreader`, which clears only the previously touched nodes.
    """
    F = _check_forces(F, stencil, backend)
    if out is None:
        out = backend.zeros(grid.field_shape)
    else:
        _check_field(out, grid, "out")
        out[...] = 0
    return _scatter(F, stencil, grid, backend, out)[0]


class Spreader:
    """Spreading (28) into a persistent, reusable grid buffer.

    ``spread(F, stencil)`` returns the internal buffer (3, N, N, N); it is overwritten by the next
    call, so consume it (e.g. FFT it) before spreading again and do not write into it. Only the
    nodes touched by the previous call are reset (their indices are copied, so the stencil may be
    refilled in place by ``prepare(..., out=stencil)``), which is much cheaper than zeroing
    3 N^3 values; the (M, 64) work arrays are reused too.
    """

    def __init__(self, grid: Grid, backend):
        self.grid = grid
        self.backend = backend
        self.buffer = backend.zeros(grid.field_shape)
        self._touched = None
        self._work = None

    def clear(self):
        self.buffer[...] = 0
        self._touched = None

    def spread(self, F, stencil: Stencil):
        F = _check_forces(F, stencil, self.backend)
        if stencil.N != self.grid.N:
            raise ConfigError(f"stencil was prepared for N={stencil.N}, grid has N={self.grid.N}")
        buf = self.buffer
        if self._touched is not None:
            zero = None if self.backend.is_gpu else _compiled_zero()
            for c in range(3):
                if zero is not None:
                    zero(buf[c].reshape(-1), self._touched.reshape(1, -1))
                else:
                    buf[c].reshape(-1)[self._touched] = 0
        idx = stencil.idx.reshape(-1)
        if self._touched is not None and self._touched.shape == idx.shape:
            self._touched[...] = idx
        else:
            self._touched = idx.copy()
        _, self._work = _scatter(F, stencil, self.grid, self.backend, buf, self._work)
        return buf


def interpolate(u, stencil: Stencil, backend, out=None, work=None):
    """Velocity at the Lagrangian points, eqs. (16)/(29): U_k = sum_m u_m delta_h(x_m - X_k) h^3.

    u : (3, N, N, N) grid field (e.g. the velocity, or Gamma of eq. 29). Returns (M, 3).
    The h^3 cancels the 1/h^3 of delta_h: it is the weighted sum with the stencil weights.
    ``work``: optional (M, 64) array of u's dtype reused for the gather.
    """
    xp = backend.xp
    N = stencil.N
    if tuple(u.shape) != (3, N, N, N):
        raise ConfigError(f"u must have shape (3, {N}, {N}, {N}), got {tuple(u.shape)}")
    M = stencil.n_points
    if out is None:
        out = xp.empty((M, 3), dtype=u.dtype)
    idx = stencil.idx
    w = stencil.w
    v = _work(work, idx.shape, u.dtype, xp)
    for c in range(3):
        if xp is np:  # mode='clip' avoids NumPy's buffered out= path (indices are valid anyway)
            np.take(u[c].reshape(-1), idx, out=v, mode="clip")  # (M, 64) gather
        else:
            xp.take(u[c].reshape(-1), idx, out=v)
        out[:, c] = xp.einsum("ij,ij->i", v, w)  # no BLAS involved for this contraction
    return out


class Coupler:
    """Per-run workspace for the IBM coupling: prepare (26-27), spread (28), interpolate (29).

    Reuses the stencil arrays, the spreading grid buffer and the (M, 64) work arrays from step to
    step (fresh arrays cost page faults every step). The Stencil returned by :meth:`prepare` and
    the grid returned by :meth:`spread` are overwritten by the next call of the same method.
    """

    def __init__(self, grid: Grid, backend, kernel: str = DEFAULT_KERNEL):
        self.grid = grid
        self.backend = backend
        self.kernel = kernel
        self.spreader = Spreader(grid, backend)
        self._stencil = None
        self._work = None

    def prepare(self, X) -> Stencil:
        self._stencil = prepare(X, self.grid, self.backend, out=self._stencil, kernel=self.kernel)
        return self._stencil

    def spread(self, F, stencil: Stencil | None = None):
        return self.spreader.spread(F, self._stencil if stencil is None else stencil)

    def interpolate(self, u, stencil: Stencil | None = None, out=None):
        st = self._stencil if stencil is None else stencil
        if self._work is None or self._work.shape != st.idx.shape or self._work.dtype != u.dtype:
            self._work = self.backend.xp.empty(st.idx.shape, dtype=u.dtype)
        return interpolate(u, st, self.backend, out=out, work=self._work)
