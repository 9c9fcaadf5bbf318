"""Periodic (time-dependent) Stokes solver on the Eulerian grid, Sec. IV B, eqs. (17)-(23) and (29).

Units: mu = 1, lengths in R, time in tau = mu R^3 / kappa; the fluid density enters as rho_bar
(dimensionless, ~1e-6 for the paper's parameters; rho_bar = 0 is steady Stokes).

Discrete operators (eqs. 17-18, symbols after eq. 22), for wave-number index k = (k_1, k_2, k_3):

    lam_k   = (2 / h^2) sum_j [1 - cos(2 pi k_j / N)]      7-point Laplacian, -L -> lam_k
    g_k     = (sin(2 pi k_j / N) / h)_j                     central-difference gradient, D -> i g_k
    xi_k    = I - g_k g_k^T / |g_k|^2                       discrete Leray projector
    alpha_k = mu lam_k / rho                                (mu = 1)

Steady Stokes (rho_bar = 0, the Re -> 0 limit of eq. 23):  u_hat_k = xi_k f_hat_k / lam_k.
Finite density, exponential update of eq. (23) and its time integral (eq. 29):

    u_hat^{n+1} = e^{-a dt} u_hat^n + (1 - e^{-a dt}) / (rho a) xi f_hat^n
    Gamma_hat^n = (1 - e^{-a dt}) / a u_hat^n + (a dt + e^{-a dt} - 1) / (rho a^2) xi f_hat^n

evaluated without cancellation or overflow for a dt -> 0 and a dt -> inf as

    (1 - e^{-x}) / a            = dt * phi1(x),     phi1(x) = -expm1(-x) / x
    (1 - e^{-x}) / (rho a)      = -expm1(-x) / lam
    (x + e^{-x} - 1)/(rho a^2)  = dt * psi(x) / lam, psi(x) = 1 - phi1(x)  (Taylor series for x < 0.1)

with x = a dt. As rho_bar -> 0 (x -> inf) these tend to 0, 1/lam and dt/lam: the steady result.

Special modes
-------------
* k = 0: set to zero. The net force on a closed membrane vanishes (sum of internal forces), so
  f_hat_0 = 0 anyway, and in the periodic frame the mean induced velocity is taken as zero
  (lam_0 = 0, the mode is not determined by the equations). The stored state u_hat_0 is kept 0.
* k != 0 with g_k = 0, i.e. every k_j in {0, N/2} (the 7 "Nyquist-type" modes): the central
  difference cannot see these modes, so no pressure gradient acts on them and the incompressibility
  constraint (22) is void; the projector is the identity there (xi_k = I) and u_hat = f_hat / lam_k.
  The sines at k_j = N/2 are set to exactly 0 (not sin(pi) ~ 1e-16).

Implementation notes (performance, CPU): real FFTs over the last 3 axes; the 1/N^3 of eq. (19) is
folded into precomputed symbol arrays (the inverse FFT runs unnormalised); the projection is done in
place, slab by slab along k_1 (cache-sized chunks), computing g.f once per mode, on the interleaved
real view of the complex spectrum (symbols repeated x2 so every NumPy loop is a contiguous
real SIMD loop). The spectral workspace is owned by the solver; pass ``out=`` to reuse an output
grid buffer and avoid page-faulting a fresh 3 N^3 array every step. Measured at N = 128 (2 cores):
the steady projection/scaling adds 10-15 ms to the 60-70 ms FFT round trip (~80 ms to 110 ms at
256^3 against ~0.8 s); the finite-density update costs about twice the steady one. Changing dt
rebuilds the per-dt symbol arrays (exp/expm1 over N^3/2 modes), so keep dt fixed where possible.

Compiled steady pass (CPU). With numba installed, the steady projection and scaling run as one compiled
pass over the spectrum (:func:`_steady_pass`): each mode's symbols are read once for its real and imaginary
parts, instead of the ~10 NumPy passes over repeated symbol arrays. It does the same float operations in the
same order, so the velocities are identical bit for bit (tested). Measured by benchmarks/bench_stokes_pass.py
(float32, pyFFTW, 1 thread, two 256^3 runs on the 2-core machine, medians of alternating pairs): the pass
takes 0.60x (128^3, 5.1 against 12.7 ms) and 0.47x (256^3, 81 against 145 ms) as long, a whole steady solve
0.95x (67 against 68 ms) and 0.91x (670 against 750 ms). ``fused=False`` keeps the NumPy passes.

Sharpened coupling. ``force_filter`` W(k) multiplies the force's spectrum before the projection:
u_hat = xi W f_hat / lam (steady) and the same W f_hat in eq. (23). With W = 1 / max(phi_hat^2, floor) this undoes the
kernel's double smoothing up to the floor (:mod:`vesicle_core.solver.kernels`, "Window deconvolution"). W is real,
even and
positive and commutes with xi / lam, so the coupled mobility stays symmetric positive semi-definite.

Spectral layouts. CPU (NumPy): the interleaved real view above, in slabs of ~1 MiB. GPU (CuPy): the
complex spectrum itself, symbols once per mode and the whole grid as one chunk (one kernel launch per
operation). ``StokesSolver(..., interleave=None)`` picks by backend; ``interleave=False`` forces the GPU
layout on NumPy (how the tests check it without a GPU), ``interleave=True`` the CPU layout. Both give the
same velocities to round-off.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..errors import ConfigError, check_range

_CHUNK_BYTES = 1 << 20  # ~1 MiB per component and chunk (measured best at N = 64-128 on 2 cores)


def laplacian_symbol_1d(N, h):
    """(2 - 2 cos(2 pi k / N)) / h^2 = 4 sin^2(pi k / N) / h^2 for k = 0..N-1 (float64)."""
    k = np.arange(N)
    return 4.0 * np.sin(np.pi * k / N) ** 2 / h**2


def gradient_symbol_1d(N, h):
    """sin(2 pi k / N) / h for k = 0..N-1, exactly 0 at k = 0 and k = N/2 (float64)."""
    k = np.arange(N)
    g = np.sin(2.0 * np.pi * k / N) / h
    g[(2 * k) % N == 0] = 0.0
    return g


def _steady_pass(Fv, g, gz, A, Bm):
    """F <- A F - g (Bm (g . F)) on the interleaved real view Fv (3, N, N, 2 Nh), one pass (see the module
    docstring); g (N,) the gradient symbol along k_1 and k_2, gz (Nh,) along k_3, A and Bm (N, N, Nh) once per
    mode. The operations and their order are those of ``StokesSolver._apply_steady``. Compiled by numba
    (:func:`_compiled_steady_pass`); far too slow as plain Python."""
    n0, n1, n2 = Fv.shape[1], Fv.shape[2], A.shape[2]
    for i in range(n0):
        gi = g[i]
        for j in range(n1):
            gj = g[j]
            for kk in range(n2):
                a = A[i, j, kk]
                bm = Bm[i, j, kk]
                gk = gz[kk]
                for c in range(2 * kk, 2 * kk + 2):
                    f0 = Fv[0, i, j, c]
                    f1 = Fv[1, i, j, c]
                    f2 = Fv[2, i, j, c]
                    d = f0 * gi
                    d = d + f1 * gj
                    d = d + f2 * gk
                    d = d * bm
                    Fv[0, i, j, c] = f0 * a - d * gi
                    Fv[1, i, j, c] = f1 * a - d * gj
                    Fv[2, i, j, c] = f2 * a - d * gk


@functools.cache
def _compiled_steady_pass():
    """:func:`_steady_pass` compiled by numba (cached on disk), or None when numba is not installed."""
    try:
        import numba
    except ImportError:
        return None
    # no fastmath: contracting a * b + c into a fused multiply-add would change the rounding
    kernel = numba.njit(cache=True, nogil=True, boundscheck=False)(_steady_pass)
    try:  # compile now: a package folder and user cache that are both read-only make caching raise here
        kernel(np.zeros((3, 2, 2, 4)), np.zeros(2), np.zeros(2), np.zeros((2, 2, 2)), np.zeros((2, 2, 2)))
    except RuntimeError:
        kernel = numba.njit(cache=False, nogil=True, boundscheck=False)(_steady_pass)
    return kernel


def _psi(x):
    """psi(x) = 1 - (1 - e^{-x})/x = (x + expm1(-x)) / x, stable for all x >= 0."""
    x = np.asarray(x, dtype=np.float64)
    out = np.empty_like(x)
    small = x < 0.1
    xs = x[small]
    # x/2 - x^2/6 + x^3/24 - ... (terms up to x^11/12!, truncation < 1e-19 relative for x < 0.1)
    poly = np.zeros_like(xs)
    for n in range(12, 1, -1):  # Horner on sum_{n>=2} (-1)^n x^{n-1} / n!
        poly = poly * xs + ((-1.0) ** n) / math.factorial(n)
    out[small] = poly * xs
    xl = x[~small]
    out[~small] = 1.0 + np.expm1(-xl) / xl
    return out


def _phi1(x):
    """phi1(x) = (1 - e^{-x}) / x, = 1 at x = 0."""
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = -np.expm1(-x) / x
    return np.where(x == 0.0, 1.0, r)


class StokesSolver:
    """Fourier solver of eqs. (21)-(23) on a periodic :class:`~vesicle_core.solver.ibm.Grid`.

    Parameters
    ----------
    grid : Grid
    backend : Backend (NumPy or CuPy; ``backend.dtype`` float32 switches to float32/complex64
        fields and symbols, see :attr:`single_precision`).
    rho_bar : dimensionless fluid density >= 0; 0 = steady Stokes.
    force_filter : None, or a real, even, positive symbol W (N, N, N // 2 + 1) (float64, host) that multiplies the
        force's spectrum: the sharpened coupling's window deconvolution (module docstring, "Sharpened coupling";
        :func:`~vesicle_core.solver.kernels.sharpening_symbol`). Folded into the symbols once: a solve costs the same.
    interleave : spectral layout of the in-place kernels (module docstring, "Spectral layouts").
        None (default): automatic, the interleaved real view in ~1 MiB slabs on NumPy and the complex
        layout in one chunk on CuPy. False: the complex, single-chunk GPU layout on any backend (lets the
        CPU tests run the GPU code path). True: the interleaved layout on any backend.
    """

    def __init__(self, grid, backend, rho_bar=0.0, interleave=None, fused=None, force_filter=None):
        if interleave is not None and not isinstance(interleave, (bool, np.bool_)):
            raise ConfigError(f"interleave must be None (automatic), True or False, got {interleave!r}")
        if fused is not None and not isinstance(fused, (bool, np.bool_)):
            raise ConfigError(f"fused must be None (automatic), True or False, got {fused!r}")
        self.grid = grid
        self.backend = backend
        self.rho_bar = float(check_range("rho_bar", rho_bar, 0.0, None))
        self.dtype = np.dtype(backend.dtype)
        self.cdtype = backend.complex_dtype
        xp = backend.xp
        N, h = grid.N, grid.h
        Nh = N // 2 + 1
        self._N3 = float(N) ** 3
        self._axes = (1, 2, 3)
        self._s = grid.shape

        lam1 = laplacian_symbol_1d(N, h)
        g1 = gradient_symbol_1d(N, h)
        lam = lam1[:, None, None] + lam1[None, :, None] + lam1[None, None, :Nh]
        g2 = g1[:, None, None] ** 2 + g1[None, :, None] ** 2 + g1[None, None, :Nh] ** 2
        lam[0, 0, 0] = 1.0  # placeholder, zeroed below
        self._inv_lam = 1.0 / lam  # float64 host copies for building the per-dt symbols
        self._inv_lam[0, 0, 0] = 0.0
        lam[0, 0, 0] = 0.0
        self.filtered = force_filter is not None
        if self.filtered:
            W = np.asarray(force_filter, dtype=np.float64)
            if W.shape != lam.shape:
                raise ConfigError(f"force_filter must have shape {lam.shape}, got {W.shape}")
            if not np.all(np.isfinite(W)) or np.any(W <= 0.0):
                raise ConfigError("force_filter must be finite and positive (a real, even window symbol)")
            # every symbol that acts on the force carries 1/lam (steady A, Bm; unsteady Q2, Q3); the decay E and
            # the carried state's Q1 do not: folding W here filters the force and nothing else
            self._inv_lam *= W
        self._lam = lam
        with np.errstate(divide="ignore"):
            self._ginv = np.where(g2 > 0.0, 1.0 / np.where(g2 > 0.0, g2, 1.0), 0.0)

        # CPU: act on the interleaved real view of the spectrum -> repeat symbols along last axis.
        # GPU (or interleave=False): the complex spectrum, one chunk.
        self._interleave = (not backend.is_gpu) if interleave is None else bool(interleave)
        rep = 2 if self._interleave else 1
        last = Nh * rep
        # g_x varies along the chunked axis (broadcast (m, 1, 1): long inner loops); g_y and g_z
        # are stored as full (N, last) planes because NumPy broadcasting of (N, 1) or (last,)
        # over a slab runs ~2x slower than a same-shape operand (short inner loops).
        self._gx = xp.asarray(g1, dtype=self.dtype)
        gz = np.repeat(g1[:Nh], rep)
        self._gy = xp.asarray(np.broadcast_to(g1[:, None], (N, last)), dtype=self.dtype)
        self._gz = xp.asarray(np.broadcast_to(gz[None, :], (N, last)), dtype=self.dtype)
        if self._interleave:
            slab = N * last * self.dtype.itemsize
            self._chunk = int(max(1, min(N, _CHUNK_BYTES // slab)))
        else:
            self._chunk = N
        self._tmp = [xp.empty((self._chunk, N, last), dtype=self.dtype if self._interleave
                              else self.cdtype) for _ in range(2)]
        self._fhat = backend.empty((3, N, N, Nh), self.cdtype)
        # the compiled steady pass (CPU, interleaved layout): None = automatic, on when numba imports
        usable = self._interleave and not backend.is_gpu
        if fused and not usable:
            raise ConfigError("fused=True needs the CPU interleaved layout (NumPy backend, interleave not False)")
        if fused and _compiled_steady_pass() is None:
            raise ConfigError("fused=True needs numba, which is not installed (pip install numba)")
        self._fused = bool(usable and _compiled_steady_pass() is not None) if fused is None else bool(fused)
        if self._fused:
            self._g1 = np.asarray(g1, dtype=self.dtype)
            self._gz1 = np.ascontiguousarray(self._g1[:Nh])

        self._steady_cache = {}  # scale -> (A, Bm)
        self._root_cache = {}  # scale -> (A, Bm) of the square root (thermal noise)
        self._dt_cache = None  # (dt, E, Q1, Q2, Q3)
        self._ginv_dev = None
        self._u_hat = None
        if self.rho_bar > 0.0:
            self._ginv_dev = self._to_dev(self._ginv)
            self._u_hat = xp.zeros((3, N, N, Nh), dtype=self.cdtype)

    # ------------------------------------------------------------------ helpers
    @property
    def single_precision(self) -> bool:
        """True when fields/symbols are float32/complex64 (backend dtype float32)."""
        return self.dtype == np.float32

    @property
    def steady(self) -> bool:
        return self.rho_bar == 0.0

    @property
    def fused(self) -> bool:
        """True when the steady projection runs as one compiled pass (numba; see the module docstring)."""
        return self._fused

    @property
    def interleaved(self) -> bool:
        """True when the kernels act on the interleaved real view (CPU layout), False for the complex
        single-chunk layout (GPU layout; see the ``interleave`` argument)."""
        return self._interleave

    def _to_dev(self, sym):
        """Host float64 symbol (N, N, Nh) -> device array in the layout the kernels use."""
        if self._interleave:
            sym = np.repeat(sym, 2, axis=-1)
        return self.backend.xp.asarray(sym, dtype=self.dtype)

    def _view(self, a):
        return a.view(self.dtype) if self._interleave else a

    def _steady_symbols(self, scale):
        return self._cached_symbols(self._steady_cache, scale, lambda: self._inv_lam)

    def _root_symbols(self, scale):
        """(A, Bm) of :meth:`_apply_steady` for scale * xi (W / lam)^{1/2} (the square root of the steady symbol)."""
        # _inv_lam carries W: sqrt(W / lam), 0 at k = 0
        return self._cached_symbols(self._root_cache, scale, lambda: np.sqrt(self._inv_lam))

    def _cached_symbols(self, cache, scale, base):
        """(A, Bm) of :meth:`_apply_steady` with A = base() * scale / N^3, cached per scale (at most four)."""
        key = float(scale)
        sym = cache.get(key)
        if sym is None:
            A = base() * (key / self._N3)
            if self._fused:  # once per mode, not repeated for the interleaved view
                sym = (A.astype(self.dtype), (A * self._ginv).astype(self.dtype))
            else:
                sym = (self._to_dev(A), self._to_dev(A * self._ginv))
            if len(cache) >= 4:
                cache.clear()
            cache[key] = sym
        return sym

    def _dt_symbols(self, dt):
        if self._dt_cache is not None and self._dt_cache[0] == dt:
            return self._dt_cache[1:]
        x = self._lam * (dt / self.rho_bar)  # alpha_k dt
        E = np.exp(-x)
        Q1 = dt * _phi1(x)
        Q2 = dt * _psi(x) * self._inv_lam / self._N3
        Q3 = -np.expm1(-x) * self._inv_lam / self._N3
        for q in (E, Q1):
            q[0, 0, 0] = 0.0  # the mean mode is kept at zero
        syms = tuple(self._to_dev(q) for q in (E, Q1, Q2, Q3))
        self._dt_cache = (dt,) + syms
        return syms

    def _check_f(self, f):
        if tuple(f.shape) != self.grid.field_shape:
            raise ConfigError(f"f must have shape {self.grid.field_shape}, got {tuple(f.shape)}")

    def _forward(self, f):
        self._check_f(f)
        return self.backend.rfftn(f, self._axes, out=self._fhat)

    def _inverse(self, F, out):
        if out is not None and tuple(out.shape) != self.grid.field_shape:
            raise ConfigError(f"out must have shape {self.grid.field_shape}, got {tuple(out.shape)}")
        return self.backend.irfftn(F, self._s, self._axes, out=out, overwrite_x=True, norm="forward")

    # ------------------------------------------------------------------ kernels (in place)
    def _chunks(self):
        n, cs = self.grid.N, self._chunk
        for i0 in range(0, n, cs):
            yield i0, min(i0 + cs, n)

    def _gdot(self, Fv, i0, i1, d, t):
        """d = g . F on slabs i0:i1 (computed once per mode)."""
        xp = self.backend.xp
        gxs = self._gx[i0:i1, None, None]
        xp.multiply(Fv[0, i0:i1], gxs, out=d)
        xp.multiply(Fv[1, i0:i1], self._gy, out=t)
        d += t
        xp.multiply(Fv[2, i0:i1], self._gz, out=t)
        d += t
        return gxs

    def _apply_steady(self, Fv, A, Bm):
        """F <- A F - g (Bm (g . F)) = (scale / N^3) xi F / lam, in place."""
        if self._fused:
            _compiled_steady_pass()(Fv, self._g1, self._gz1, A, Bm)
            return
        xp = self.backend.xp
        for i0, i1 in self._chunks():
            m = i1 - i0
            d, t = self._tmp[0][:m], self._tmp[1][:m]
            gxs = self._gdot(Fv, i0, i1, d, t)
            d *= Bm[i0:i1]
            Ac = A[i0:i1]
            for c, gc in ((0, gxs), (1, self._gy), (2, self._gz)):
                Fc = Fv[c, i0:i1]
                Fc *= Ac
                xp.multiply(d, gc, out=t)
                Fc -= t

    def _apply_unsteady(self, Fv, Uv, E, Q1, Q2, Q3):
        """P = xi F; then Gamma = Q1 U + Q2 P (into F) and U <- E U + Q3 P, in place."""
        xp = self.backend.xp
        ginv = self._ginv_dev
        for i0, i1 in self._chunks():
            m = i1 - i0
            d, t = self._tmp[0][:m], self._tmp[1][:m]
            gxs = self._gdot(Fv, i0, i1, d, t)
            d *= ginv[i0:i1]
            for c, gc in ((0, gxs), (1, self._gy), (2, self._gz)):
                xp.multiply(d, gc, out=t)
                Fv[c, i0:i1] -= t
            Ec, Q1c, Q2c, Q3c = E[i0:i1], Q1[i0:i1], Q2[i0:i1], Q3[i0:i1]
            for c in range(3):
                P, U = Fv[c, i0:i1], Uv[c, i0:i1]
                xp.multiply(U, Q1c, out=t)
                U *= Ec
                xp.multiply(P, Q3c, out=d)
                U += d
                P *= Q2c
                P += t

    # ------------------------------------------------------------------ public API
    def velocity(self, f, out=None):
        """Steady Stokes velocity u = L^{-1} xi f (rho -> 0 limit of eq. 23) for f (3, N, N, N).

        Returns (3, N, N, N) in backend dtype; written into ``out`` when given.
        """
        F = self._forward(f)
        A, Bm = self._steady_symbols(1.0)
        self._apply_steady(self._view(F), A, Bm)
        return self._inverse(F, out)

    def sqrt_velocity(self, z, scale=1.0, out=None):
        """scale * (xi W / lam)^{1/2} z = scale * xi (W / lam)^{1/2} z for a grid field z (3, N, N, N).

        The symmetric square root of the steady operator of :meth:`velocity` (xi is a projector and commutes with
        the real, even scalar W / lam, so applying this twice is ``velocity``): zero at k = 0, xi = I at the
        Nyquist-type modes, the force filter W entering as sqrt(W). Applied to white noise it gives the
        fluctuating-Stokes velocity of :mod:`vesicle_core.solver.fluctuations`. One FFT round trip, like ``velocity``;
        steady (rho -> 0) operator whatever ``rho_bar`` is.
        """
        F = self._forward(z)
        A, Bm = self._root_symbols(float(scale))
        self._apply_steady(self._view(F), A, Bm)
        return self._inverse(F, out)

    def step(self, f, dt, out=None):
        """Gamma = int_t^{t+dt} u_ind ds on the grid (eq. 29) for the force density f held constant.

        Finite rho_bar: exponential update (23) of the stored u_hat, which is advanced to t + dt.
        rho_bar == 0: returns velocity(f) * dt (the dt is folded into the symbols, no extra pass).
        """
        dt = float(check_range("dt", dt, 0.0, None, lo_open=True))
        F = self._forward(f)
        if self.steady:
            A, Bm = self._steady_symbols(dt)
            self._apply_steady(self._view(F), A, Bm)
        else:
            E, Q1, Q2, Q3 = self._dt_symbols(dt)
            self._apply_unsteady(self._view(F), self._view(self._u_hat), E, Q1, Q2, Q3)
        return self._inverse(F, out)

    def velocity_field(self, out=None):
        """Current induced velocity u_ind on the grid from the stored u_hat (finite rho_bar only)."""
        if self.steady:
            raise ConfigError("velocity_field needs rho_bar > 0 (steady Stokes stores no state)")
        F = self._fhat
        F[...] = self._u_hat
        return self._inverse(F, out)

    def reset(self):
        """Fluid at rest: u_hat = 0."""
        if self._u_hat is not None:
            self._u_hat[...] = 0

    @property
    def state(self) -> dict:
        """Checkpoint state: {'rho_bar': float, 'u_hat': complex array (3, N, N, N//2+1) or None}.

        u_hat follows eq. (19) (normalised by 1/N^3, real-FFT half spectrum along the last axis),
        returned as a host NumPy copy.
        """
        u_hat = None if self._u_hat is None else self.backend.asnumpy(self._u_hat).copy()
        return {"rho_bar": self.rho_bar, "u_hat": u_hat}

    @state.setter
    def state(self, value):
        u_hat = value.get("u_hat") if isinstance(value, dict) else value
        if self.steady:
            if u_hat is not None and np.any(np.asarray(u_hat) != 0):
                raise ConfigError("cannot load a non-zero u_hat into a steady (rho_bar = 0) solver")
            return
        if u_hat is None:
            self.reset()
            return
        shape = (3,) + self.grid.spectral_shape
        if tuple(np.shape(u_hat)) != shape:
            raise ConfigError(f"u_hat must have shape {shape}, got {tuple(np.shape(u_hat))}")
        self._u_hat[...] = self.backend.asarray(u_hat, dtype=self.cdtype)
        self._u_hat[:, 0, 0, 0] = 0
