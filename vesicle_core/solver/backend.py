"""Array backend: NumPy (CPU) or CuPy (GPU), and the real FFTs and scatter-add that the IBM needs.

The Stokes solve of Sec. IV B (eqs. 19-23, 29) is dominated by the 3-component real FFT round trip
of the Eulerian grid; spreading (28) needs a scatter-add with repeated indices. This module hides
the library behind those two operations:

* CPU, FFT: pyFFTW plans (cached per shape/dtype/axes) when pyFFTW is importable, else ``scipy.fft``.
  On the 2-core reference VM (noisy to ~30 %) a 3 x 128^3 rfftn + irfftn round trip took 60-90 ms
  with single-threaded pyFFTW against 125-170 ms with ``scipy.fft`` (workers=1); at 3 x 256^3,
  0.77 s (pyFFTW, FFTW_MEASURE plan) against 2.2 s (scipy) and 2.7 s (pyFFTW, FFTW_ESTIMATE).
  ``fft_workers`` defaults to 1, because a sweep runs one job per core; a single run on an idle 2-core
  machine should pass 2: one steady Stokes solve then takes 0.71x (128^3) and 0.65x (256^3) as long
  (benchmarks/bench_fft_threads.py, docs/history/solver.md).
* CPU, scatter-add: ``np.add.at`` into an existing buffer. With NumPy 2.x it costs ~0.6 ms for
  2562 x 64 entries into a 128^3 grid, whereas ``out += np.bincount(idx, vals, minlength=out.size)``
  costs ~2.2 ms because it builds and adds a full-size temporary. ``bincount`` is offered for the
  case of a *fresh* output (:meth:`Backend.bincount`).
* GPU: ``cupy.fft`` and ``cupyx.scatter_add``. CuPy is imported lazily, only in this module.
* ``fft_library='numpy'`` (CPU, testing only): the FFTs go through the array module's own ``xp.fft``,
  the code path the CuPy backend takes (``cupy.fft`` mirrors ``numpy.fft``), so that branch runs and is
  tested without a GPU. ``numpy.fft`` is single-threaded and slower than pyFFTW/scipy; ``auto`` never
  picks it.

Normalisation. ``rfftn`` is the unnormalised forward transform (sum over nodes). ``irfftn`` scales
by 1/prod(s) by default (``norm='backward'``, as NumPy); ``norm='forward'`` skips the scaling so a
solver can fold the 1/N^3 of eq. (19) into its precomputed symbols instead of a pass over the grid.

Reproducibility. An FFTW_MEASURE plan is chosen by timing candidate algorithms, so two processes can pick
different plans for the same transform, whose results differ in the last bits: three processes planning the
same 3 x 256^3 float32 r2c transform gave three different outputs. A wrinkling run amplifies that to ~0.1% in
l_* (two 256^3 runs of the same case: 25.182 and 25.202). So measured plans go through FFTW wisdom kept on
disk (:func:`fftw_wisdom_path`; ``VESICLE_FFTW_WISDOM=off`` disables it): the first process on a machine
plans and stores its choice, every later one reuses it, and repeated runs are identical bit for bit (and skip
the planning time). FFTW_ESTIMATE plans (below 256^3 by default) are deterministic without wisdom.

Thread safety: a Backend caches FFTW plans and scratch arrays; do not share one Backend between
threads that transform concurrently.
"""

from __future__ import annotations

import base64
import contextlib
import json
import logging
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from ..errors import ConfigError

log = logging.getLogger("vesicle_core.solver.backend")

BACKEND_NAMES = ("numpy", "cupy", "auto")
DTYPES = ("float64", "float32")
FFT_LIBRARIES = ("auto", "pyfftw", "scipy", "numpy")
FFTW_PLANNERS = ("auto", "FFTW_ESTIMATE", "FFTW_MEASURE", "FFTW_PATIENT", "FFTW_EXHAUSTIVE")
# 'auto' planner: FFTW_ESTIMATE below this many points per transform, FFTW_MEASURE from it on.
# Measured on the 2-core reference machine (3-component batched r2c): at 128^3 MEASURE (1.4 s of
# planning) was not faster than ESTIMATE (55-70 ms round trip either way, noise); at 256^3 the
# ESTIMATE plan took 1.33 s per direction against 0.33 s for MEASURE (3.6 s of planning, once per
# process and shape thanks to FFTW wisdom).
AUTO_MEASURE_POINTS = 1 << 23
_COMPLEX = {np.dtype("float64"): np.dtype("complex128"), np.dtype("float32"): np.dtype("complex64")}


WISDOM_ENV = "VESICLE_FFTW_WISDOM"
_WISDOM_FORMAT = 1


def fftw_wisdom_path() -> Path | None:
    """Where measured FFTW plans are kept: ``$VESICLE_FFTW_WISDOM`` (a file path; 'off', 'none', '0' or empty
    disable it), else ``$XDG_CACHE_HOME/vesicle-wrinkling/fftw-wisdom.json`` (``~/.cache`` by default). Wisdom
    is specific to the machine's FFTW build and CPU; FFTW ignores entries it cannot use."""
    value = os.environ.get(WISDOM_ENV)
    if value is not None:
        value = value.strip()
        if value.lower() in ("", "off", "none", "0"):
            return None
        return Path(value).expanduser()
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(cache) / "vesicle-wrinkling" / "fftw-wisdom.json"


def _read_wisdom(path: Path):
    data = json.loads(path.read_text())
    if data.get("format") != _WISDOM_FORMAT:
        raise ValueError(f"unknown format {data.get('format')!r}")
    return tuple(base64.b64decode(w) for w in data["wisdom"])


def _write_wisdom(path: Path, wisdom) -> None:
    text = json.dumps({"format": _WISDOM_FORMAT, "wisdom": [base64.b64encode(w).decode("ascii") for w in wisdom]})
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.chmod(tmp, 0o644)  # mkstemp makes it private; a shared cache should be readable by the group
        os.replace(tmp, path)  # atomic: a reader sees the old wisdom or the new, never half a file
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def persistent_wisdom(pyfftw):
    """Plan inside this block with the wisdom on disk loaded first and saved after (see the module docstring).

    An exclusive lock on ``<path>.lock`` serialises planning between processes, so two runs that start together
    use one plan: the second waits for the first's wisdom instead of measuring its own. A cache that cannot be
    read or written only costs the reproducibility (a warning); it never stops a run.
    """
    path = fftw_wisdom_path()
    lock = None
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            lock = open(path.with_name(path.name + ".lock"), "a")  # closed in the finally below
        except OSError as exc:
            log.warning("FFTW wisdom %s not usable (%s): plans are measured afresh, runs may differ in the "
                        "last bits", path, exc)
    if lock is None:
        yield
        return
    try:
        with contextlib.suppress(ImportError, OSError):
            import fcntl

            fcntl.flock(lock, fcntl.LOCK_EX)
        if path.exists():
            try:
                pyfftw.import_wisdom(_read_wisdom(path))
            except (OSError, ValueError, KeyError, TypeError) as exc:
                log.warning("FFTW wisdom %s unreadable (%s): it will be rewritten", path, exc)
        yield
        try:
            _write_wisdom(path, pyfftw.export_wisdom())
        except OSError as exc:
            log.warning("FFTW wisdom %s not written (%s)", path, exc)
    finally:
        lock.close()  # releases the lock


def _import_pyfftw():
    try:
        import pyfftw  # noqa: F401

        return pyfftw
    except Exception:  # missing, or a broken binary: fall back to scipy.fft
        return None


def cupy_available() -> bool:
    """True when CuPy imports and at least one CUDA device is visible."""
    try:
        import cupy

        return int(cupy.cuda.runtime.getDeviceCount()) > 0
    except Exception:
        return False


@dataclass
class Backend:
    """Array module plus FFT / scatter-add primitives.

    Fields
    ------
    name : 'numpy' | 'cupy'
    xp : the array module (numpy or cupy)
    dtype : real floating dtype of grid fields (float64, or float32 when asked)
    fft_workers : threads for the CPU FFT (pyFFTW ``threads`` / scipy ``workers``)
    fft_library : 'pyfftw' | 'scipy' (| 'numpy': the GPU code path ``xp.fft``, for tests) on CPU, 'cupy' on GPU
    fft_planner : FFTW planner effort for pyFFTW plans ('auto': see AUTO_MEASURE_POINTS)
    """

    name: str
    xp: ModuleType
    dtype: Any = np.dtype("float64")
    fft_workers: int = 1
    fft_library: str = "scipy"
    fft_planner: str = "auto"
    _plans: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        self.dtype = np.dtype(self.dtype)

    # ------------------------------------------------------------------ dtypes and allocation
    @property
    def complex_dtype(self):
        """complex128 for float64, complex64 for float32."""
        return _COMPLEX[self.dtype]

    @property
    def is_gpu(self) -> bool:
        return self.name == "cupy"

    @property
    def uses_xp_fft(self) -> bool:
        """True when the FFTs call the array module's own ``xp.fft`` (always on GPU; on CPU with
        ``fft_library='numpy'``, which runs the GPU code path on NumPy arrays)."""
        return self.is_gpu or self.fft_library == "numpy"

    def empty(self, shape, dtype=None):
        """Uninitialised array; SIMD-aligned on CPU when pyFFTW is in use (lets FFTW skip copies)."""
        dtype = self.dtype if dtype is None else np.dtype(dtype)
        if self.fft_library == "pyfftw":
            import pyfftw

            return pyfftw.empty_aligned(shape, dtype=dtype)
        return self.xp.empty(shape, dtype=dtype)

    def zeros(self, shape, dtype=None):
        dtype = self.dtype if dtype is None else np.dtype(dtype)
        if self.fft_library == "pyfftw":
            import pyfftw

            return pyfftw.zeros_aligned(shape, dtype=dtype)
        return self.xp.zeros(shape, dtype=dtype)

    def asarray(self, a, dtype=None):
        """Array on this backend's device (no copy when already there with the right dtype)."""
        return self.xp.asarray(a, dtype=dtype)

    def asnumpy(self, a):
        """Host NumPy array (a copy from the device on GPU)."""
        if self.is_gpu:
            import cupy

            return cupy.asnumpy(a)
        return np.asarray(a)

    # ------------------------------------------------------------------ FFTs
    def rfftn(self, a, axes, out=None):
        """Unnormalised real-to-complex FFT over ``axes`` (last axis halved to n//2 + 1).

        ``out``, if given, receives the result (must have the right shape and complex dtype).
        The input is preserved.
        """
        axes = _norm_axes(axes, a.ndim)
        if self.fft_library == "pyfftw":
            return self._fftw_r2c(a, axes, out)
        a = a.astype(self.dtype, copy=False)  # float32 runs stay in single precision (complex64)
        if self.uses_xp_fft:
            res = self.xp.fft.rfftn(a, axes=axes)
        else:
            import scipy.fft as sfft

            res = sfft.rfftn(a, axes=axes, workers=self.fft_workers)
        return _into(res, out)

    def irfftn(self, a, s, axes, out=None, overwrite_x=False, norm="backward"):
        """Complex-to-real inverse FFT over ``axes`` with real output lengths ``s``.

        norm='backward' divides by prod(s) (NumPy convention, ``irfftn(rfftn(x)) == x``);
        norm='forward' leaves the sum unscaled. ``overwrite_x=True`` allows the input to be destroyed
        (saves a copy with FFTW, whose multi-dimensional c2r always destroys its input).
        """
        if norm not in ("backward", "forward"):
            raise ConfigError(f"norm must be one of ('backward', 'forward'), got {norm!r}")
        axes = _norm_axes(axes, a.ndim)
        s = tuple(int(n) for n in s)
        if self.fft_library == "pyfftw":
            res = self._fftw_c2r(a, s, axes, out, overwrite_x)
            if norm == "backward":
                res *= 1.0 / math.prod(s)
            return res
        if self.uses_xp_fft:
            res = self.xp.fft.irfftn(a, s=s, axes=axes, norm=norm)
        else:
            import scipy.fft as sfft

            res = sfft.irfftn(a, s=s, axes=axes, workers=self.fft_workers, norm=norm,
                              overwrite_x=overwrite_x)
        return _into(res, out)

    def _plan(self, kind, in_shape, axes, s=None):
        """Cached pyFFTW plan (FFTW object, output shape) for one transform signature.

        The planning arrays are dropped after planning; each call binds the caller's arrays with
        ``update_arrays`` and runs ``execute()`` (never ``__call__``, which would copy unaligned
        input into "the current input array", possibly a caller's array from an earlier call).
        The plan keeps a reference to the arrays of its last call only.
        """
        key = (kind, tuple(in_shape), self.dtype.str, axes, s)
        plan = self._plans.get(key)
        if plan is not None:
            return plan
        import pyfftw

        rdt, cdt = self.dtype, self.complex_dtype
        npts = math.prod(in_shape[ax] for ax in axes) if kind == "r2c" else math.prod(s)
        effort = self.fft_planner
        if effort == "auto":
            effort = "FFTW_MEASURE" if npts >= AUTO_MEASURE_POINTS else "FFTW_ESTIMATE"
        out_shape = list(in_shape)
        # a measured plan depends on timings, so it goes through the wisdom on disk; an estimated one is
        # deterministic and needs none
        wisdom = contextlib.nullcontext() if effort == "FFTW_ESTIMATE" else persistent_wisdom(pyfftw)
        if kind == "r2c":
            out_shape[axes[-1]] = in_shape[axes[-1]] // 2 + 1
            ain = pyfftw.empty_aligned(in_shape, dtype=rdt)
            aout = pyfftw.empty_aligned(tuple(out_shape), dtype=cdt)
            with wisdom:
                obj = pyfftw.FFTW(ain, aout, axes=axes, direction="FFTW_FORWARD",
                                  flags=(effort,), threads=self.fft_workers)
        else:
            for ax, n in zip(axes, s, strict=True):
                out_shape[ax] = n
            ain = pyfftw.empty_aligned(in_shape, dtype=cdt)
            aout = pyfftw.empty_aligned(tuple(out_shape), dtype=rdt)
            with wisdom:
                obj = pyfftw.FFTW(ain, aout, axes=axes, direction="FFTW_BACKWARD",
                                  flags=(effort, "FFTW_DESTROY_INPUT"), threads=self.fft_workers)
        plan = (obj, tuple(out_shape))
        self._plans[key] = plan
        return plan

    def _scratch_for(self, a, dtype):
        """Aligned scratch copy of ``a`` (buffer cached per shape/dtype)."""
        key = ("scratch", tuple(a.shape), np.dtype(dtype).str)
        buf = self._plans.get(key)
        if buf is None:
            buf = self.empty(a.shape, dtype)
            self._plans[key] = buf
        buf[...] = a
        return buf

    def _fftw_r2c(self, a, axes, out):
        a = np.asarray(a)
        obj, out_shape = self._plan("r2c", a.shape, axes)
        if a.dtype != self.dtype or not _fits(a, obj.input_alignment):
            a = self._scratch_for(a, self.dtype)
        target = out if (out is not None and _fits(out, obj.output_alignment)
                         and out.shape == out_shape and out.dtype == self.complex_dtype) else None
        if target is None:
            target = self.empty(out_shape, self.complex_dtype)
        obj.update_arrays(a, target)
        obj.execute()
        return _into(target, out)

    def _fftw_c2r(self, a, s, axes, out, overwrite_x):
        a = np.asarray(a)
        obj, out_shape = self._plan("c2r", a.shape, axes, s)
        if not overwrite_x or a.dtype != self.complex_dtype or not _fits(a, obj.input_alignment):
            a = self._scratch_for(a, self.complex_dtype)
        target = out if (out is not None and _fits(out, obj.output_alignment)
                         and out.shape == out_shape and out.dtype == self.dtype) else None
        if target is None:
            target = self.empty(out_shape, self.dtype)
        obj.update_arrays(a, target)
        obj.execute()
        return _into(target, out)

    # ------------------------------------------------------------------ scatter
    def scatter_add(self, out_flat, idx_flat, vals):
        """out_flat[idx] += vals, accumulating repeated indices (the sum of eq. 28).

        CPU: ``np.add.at`` (in NumPy 2.x faster than ``out += bincount(...)`` into a persistent
        buffer, see module docstring); GPU: ``cupyx.scatter_add``.
        """
        if self.is_gpu:
            import cupyx

            cupyx.scatter_add(out_flat, idx_flat, vals)
        else:
            np.add.at(out_flat, idx_flat, vals)
        return out_flat

    def bincount(self, idx_flat, vals, size):
        """Fresh array of length ``size`` with the sums of ``vals`` per index (float64 on CPU)."""
        return self.xp.bincount(idx_flat, weights=vals, minlength=size)


def _norm_axes(axes, ndim):
    return tuple(int(ax) % ndim for ax in axes)


def _fits(a, alignment):
    return (isinstance(a, np.ndarray) and a.flags.c_contiguous
            and a.ctypes.data % max(int(alignment), 1) == 0)


def _into(res, out):
    if out is None or res is out:
        return res
    out[...] = res
    return out


def get_backend(name="numpy", dtype="float64", fft_workers=1, fft_library="auto",
                fft_planner="auto") -> Backend:
    """Build a :class:`Backend`.

    name : 'numpy', 'cupy' or 'auto' ('auto' = CuPy when it imports and a CUDA device exists,
           else NumPy).
    dtype : 'float64' (default) or 'float32' (grid fields and FFTs in single precision).
    fft_workers : threads for the CPU FFT (>= 1).
    fft_library : CPU only: 'auto' (pyFFTW if importable, else scipy.fft), 'pyfftw', 'scipy', or 'numpy'
           (``numpy.fft`` through ``xp.fft``: the FFT code path of the CuPy backend, for testing it on the
           CPU; slower, never chosen by 'auto'). Ignored for 'cupy' (always ``cupy.fft``).
    fft_planner : FFTW planner effort for pyFFTW: 'auto' (default: FFTW_ESTIMATE below 2^23 points
           per transform, FFTW_MEASURE from 256^3 on, where it was 4x faster), or an explicit
           'FFTW_ESTIMATE' / 'FFTW_MEASURE' / 'FFTW_PATIENT' / 'FFTW_EXHAUSTIVE'.
    """
    if not isinstance(name, str) or name.lower() not in BACKEND_NAMES:
        raise ConfigError(f"backend name must be one of {BACKEND_NAMES}, got {name!r}")
    name = name.lower()
    try:
        dt = np.dtype(dtype)
    except TypeError:
        dt = None
    if dt is None or dt.name not in DTYPES:
        raise ConfigError(f"dtype must be one of {DTYPES}, got {dtype!r}")
    if isinstance(fft_workers, bool) or not isinstance(fft_workers, (int, np.integer)) or fft_workers < 1:
        raise ConfigError(f"fft_workers must be an integer >= 1, got {fft_workers!r}")
    if fft_library not in FFT_LIBRARIES:
        raise ConfigError(f"fft_library must be one of {FFT_LIBRARIES}, got {fft_library!r}")
    if fft_planner not in FFTW_PLANNERS:
        raise ConfigError(f"fft_planner must be one of {FFTW_PLANNERS}, got {fft_planner!r}")

    if name == "auto":
        name = "cupy" if cupy_available() else "numpy"
    if name == "cupy":
        try:
            import cupy
        except Exception as exc:
            raise ConfigError(f"backend name 'cupy' needs CuPy, which failed to import: {exc}") from exc
        if not cupy_available():
            raise ConfigError("backend name 'cupy' needs a CUDA device; none is visible")
        return Backend("cupy", cupy, dt, int(fft_workers), "cupy", fft_planner)

    lib = fft_library
    if lib == "auto":
        lib = "pyfftw" if _import_pyfftw() is not None else "scipy"
    elif lib == "pyfftw" and _import_pyfftw() is None:
        raise ConfigError("fft_library 'pyfftw' requested but pyFFTW is not importable; "
                          "use 'scipy' or 'auto', or install it: pip install -e '.[fast]'")
    return Backend("numpy", np, dt, int(fft_workers), lib, fft_planner)
