"""A strict CuPy stand-in: device arrays of their own type, and a count of every transfer between host and device.

The ``fake_cupy`` fixture answers with plain NumPy arrays, so it cannot see the faults real CuPy raises or hides.
Here a "device" array is a :class:`StrictArray`, a distinct type wrapping a NumPy array, and the module built by
:func:`make_modules` implements the part of CuPy's API the package calls, each name checked against CuPy's own
``cupy/__init__.py``, ``cupy/fft``, ``cupy/linalg``, ``cupy/cuda`` and ``cupyx`` (no call CuPy lacks).

What raises ``TypeError`` (as real CuPy does):
* ``np.asarray(x)`` / ``__array__`` (CuPy: "Implicit conversion to a NumPy array is not allowed");
* a host ``numpy.ndarray`` passed to a ``cupy`` function or mixed into arithmetic with a device array (CuPy's
  ``__array_ufunc__`` refuses NumPy operands; only ``cupy.asarray``/``cupy.array`` take host data).

What raises where real CuPy is more lenient (deliberately stricter, so every transfer in the package is explicit
and counted):
* any NumPy or SciPy function applied to a device array (CuPy dispatches many NumPy functions through
  ``__array_function__``/``__array_ufunc__``; SciPy's call ``np.asarray`` and fail there). The package's rule is
  ``xp`` from the arrays, so a NumPy call on a device array is a bug even where CuPy would dispatch it;
* ``float()``, ``int()``, ``bool()``, ``complex()``, ``.item()``, ``.tolist()`` (``len()`` and ``.shape`` stay
  allowed: they read no data). Real CuPy answers these with a hidden device synchronisation
  (``float(self.get())``); here a scalar must be read through ``cupy.asnumpy``/``.get()``
  (vesicle_core.xp.to_float), which counts it;
* a host NumPy array as an index or as the value of an item assignment (real CuPy copies it to the device
  silently).

Counted (:class:`Transfers`): device-to-host copies (``cupy.asnumpy``, ``.get()``) of more than one element and
their bytes; synchronising scalar reads (the same of one element); host-to-device copies (``cupy.asarray`` /
``cupy.array`` of host data) and their bytes.
"""

from __future__ import annotations

import operator
import sys
import time
import types
from dataclasses import dataclass, field

import numpy as np

IMPLICIT = ("Implicit conversion to a NumPy array is not allowed. Please use `.get()` to construct a NumPy array "
            "explicitly.")


@dataclass
class Transfers:
    """Counts of what crossed between host and device (see the module docstring)."""

    d2h: int = 0
    d2h_bytes: int = 0
    scalar_reads: int = 0
    h2d: int = 0
    h2d_bytes: int = 0
    log: list = field(default_factory=list)  # (kind, shape, where) of each, when ``trace`` is on
    trace: bool = False

    def snapshot(self) -> dict:
        return {"d2h": self.d2h, "d2h_bytes": self.d2h_bytes, "scalar_reads": self.scalar_reads, "h2d": self.h2d,
                "h2d_bytes": self.h2d_bytes}

    def reset(self):
        self.d2h = self.d2h_bytes = self.scalar_reads = self.h2d = self.h2d_bytes = 0
        self.log.clear()

    def _note(self, kind, a):
        if self.trace:
            f = sys._getframe(3)
            self.log.append((kind, tuple(a.shape), f"{f.f_code.co_filename.rsplit('/', 1)[-1]}:{f.f_lineno} "
                                                   f"{f.f_code.co_name}"))


def _refuse(what):
    def method(self, *args, **kwargs):
        raise TypeError(f"{what} of a device array: read it explicitly with cupy.asnumpy(x) or x.get() "
                        f"(strict CuPy stand-in)")
    return method


def _scalar_operand(x):
    return isinstance(x, (bool, int, float, complex, np.generic))


class StrictArray:
    """A device array: a NumPy array that NumPy cannot see (module docstring)."""

    __slots__ = ("_a", "_t")
    __array_priority__ = 1000

    def __init__(self, a: np.ndarray, transfers: Transfers):
        self._a = a
        self._t = transfers

    # ---------------------------------------------------------------- what CuPy refuses (or the stand-in does)
    def __array__(self, *args, **kwargs):
        raise TypeError(IMPLICIT)

    # NumPy ufuncs (np.sqrt(x), np.add.at(x, ...)) raise TypeError, and NumPy scalars' operators defer to ours
    __array_ufunc__ = None

    def __array_function__(self, func, types, args, kwargs):
        raise TypeError(f"NumPy function {func.__module__}.{func.__name__} on a device array: use the cupy (xp) "
                        f"function (strict CuPy stand-in)")

    __float__ = _refuse("float()")
    __int__ = _refuse("int()")
    __index__ = _refuse("int() / index")
    __complex__ = _refuse("complex()")
    __bool__ = _refuse("bool()")
    item = _refuse(".item()")
    tolist = _refuse(".tolist()")

    def __repr__(self):  # no data: printing a device array would be a transfer
        return f"StrictArray(shape={self._a.shape}, dtype={self._a.dtype})"

    __str__ = __repr__

    # ---------------------------------------------------------------- explicit transfer
    def get(self, stream=None, order="C", out=None, blocking=True):
        return _to_host(self)

    # ---------------------------------------------------------------- attributes
    shape = property(lambda self: self._a.shape)
    ndim = property(lambda self: self._a.ndim)
    size = property(lambda self: self._a.size)
    dtype = property(lambda self: self._a.dtype)
    itemsize = property(lambda self: self._a.itemsize)
    nbytes = property(lambda self: self._a.nbytes)
    strides = property(lambda self: self._a.strides)
    flags = property(lambda self: self._a.flags)
    T = property(lambda self: self._w(self._a.T))
    real = property(lambda self: self._w(self._a.real))
    imag = property(lambda self: self._w(self._a.imag))

    def __len__(self):
        return len(self._a)

    def __iter__(self):
        if self._a.ndim == 0:
            raise TypeError("iteration over a 0-d array")
        return (self[i] for i in range(self._a.shape[0]))

    def _w(self, r):
        return _wrap(r, self._t)

    # ---------------------------------------------------------------- methods (those of cupy.ndarray)
    def _method(name):
        def m(self, *args, **kwargs):
            return _wrap(getattr(self._a, name)(*_unwrap(args, name), **_unwrap(kwargs, name)), self._t)
        m.__name__ = name
        return m

    for _name in ("reshape", "ravel", "copy", "astype", "view", "sum", "mean", "max", "min", "any", "all",
                  "transpose", "fill", "conj", "argmax", "argmin", "cumsum", "dot", "squeeze", "swapaxes",
                  "flatten", "var", "std", "prod", "clip", "round", "nonzero", "take", "repeat"):
        locals()[_name] = _method(_name)
    del _name, _method

    # ---------------------------------------------------------------- indexing
    def __getitem__(self, key):
        return self._w(self._a[_index(key)])

    def __setitem__(self, key, value):
        if isinstance(value, np.ndarray):
            raise TypeError("assigning a host numpy array into a device array: copy it with cupy.asarray first "
                            "(strict CuPy stand-in)")
        self._a[_index(key)] = value._a if isinstance(value, StrictArray) else value


def _binop(name, reflected=False):
    op = getattr(operator, name)

    def f(self, other):
        if isinstance(other, StrictArray):
            o = other._a
        elif _scalar_operand(other):
            o = other
        elif isinstance(other, np.ndarray):
            raise TypeError(f"Unsupported type {type(other)} in {name} with a device array: copy it with "
                            f"cupy.asarray first")
        else:
            return NotImplemented
        r = op(o, self._a) if reflected else op(self._a, o)
        if name.startswith("i"):  # in place: keep this wrapper
            return self
        return self._w(r)
    return f


for _op in ("add", "sub", "mul", "truediv", "floordiv", "mod", "pow", "matmul", "and_", "or_", "xor", "lt", "le",
            "gt", "ge", "eq", "ne", "lshift", "rshift"):
    _dunder = _op.rstrip("_")
    setattr(StrictArray, f"__{_dunder}__", _binop(_op))
    if _op not in ("lt", "le", "gt", "ge", "eq", "ne"):
        setattr(StrictArray, f"__r{_dunder}__", _binop(_op, reflected=True))
        setattr(StrictArray, f"__i{_dunder}__", _binop(f"i{_dunder}"))
for _op in ("neg", "pos", "abs", "invert"):
    setattr(StrictArray, f"__{_op}__", (lambda o: lambda self: self._w(getattr(operator, o)(self._a)))(_op))
StrictArray.__hash__ = None


def _index(key):
    if isinstance(key, tuple):
        return tuple(_index(k) for k in key)
    if isinstance(key, StrictArray):
        return key._a
    if isinstance(key, np.ndarray):
        raise TypeError("a host numpy array as an index of a device array: copy it with cupy.asarray first "
                        "(strict CuPy stand-in)")
    if isinstance(key, list):
        return [_index(k) for k in key]
    return key


def _unwrap(x, where):
    if isinstance(x, StrictArray):
        return x._a
    if isinstance(x, np.ndarray):
        raise TypeError(f"a host numpy array passed to cupy {where}: copy it with cupy.asarray first "
                        f"(strict CuPy stand-in)")
    if isinstance(x, (list, tuple)):
        return type(x)(_unwrap(v, where) for v in x)
    if isinstance(x, dict):
        return {k: _unwrap(v, where) for k, v in x.items()}
    return x


def _wrap(r, t):
    if isinstance(r, np.ndarray):
        return StrictArray(r, t)
    if isinstance(r, np.generic):  # CuPy's reductions and scalar indexing give 0-d arrays, never host scalars
        return StrictArray(np.asarray(r), t)
    if isinstance(r, tuple):
        return tuple(_wrap(v, t) for v in r)
    if isinstance(r, list):
        return [_wrap(v, t) for v in r]
    return r


def _to_host(a: StrictArray) -> np.ndarray:
    t = a._t
    if a._a.size <= 1:
        t.scalar_reads += 1
        t._note("scalar", a._a)
    else:
        t.d2h += 1
        t.d2h_bytes += a._a.nbytes
        t._note("d2h", a._a)
    return np.array(a._a, copy=True)


#: the cupy functions the package (and benchmarks/gpu_check.py) call, NumPy's semantics; every name is one of
#: ``cupy/__init__.py``'s (checked against CuPy's source, 2026-08)
FUNCTIONS = (
    "zeros", "empty", "ones", "zeros_like", "empty_like", "ones_like", "full", "arange", "linspace",
    "add", "subtract", "multiply", "divide", "true_divide", "negative", "power", "einsum", "take", "floor", "sqrt",
    "clip", "where", "stack", "concatenate", "abs", "absolute", "sum", "mean", "median", "isfinite", "bincount",
    "broadcast_to", "ascontiguousarray", "vdot", "dot", "exp", "expm1", "log", "maximum", "minimum", "cos", "sin",
    "arccos", "arctan2", "repeat", "cross", "matmul", "outer", "all", "any", "max", "min", "amax", "amin", "argmax",
    "cumsum", "nonzero", "flatnonzero", "round", "tile", "count_nonzero", "square", "sign", "isnan", "logical_not",
    "logical_and", "logical_or", "allclose", "real", "imag", "conj", "reshape", "transpose", "moveaxis", "diff",
    "searchsorted", "sort", "argsort", "unique", "hypot", "arcsin", "arctan", "tan", "zeros", "copy", "atleast_1d",
)
DTYPES = ("float64", "float32", "int64", "int32", "intp", "uint64", "complex64", "complex128", "bool_", "dtype",
          "newaxis", "pi", "inf", "nan", "e")


def make_modules(transfers: Transfers | None = None):
    """-> (cupy, cupyx) stand-in modules sharing one :class:`Transfers` (``cupy.transfers``)."""
    t = transfers if transfers is not None else Transfers()
    cp = types.ModuleType("cupy")
    cp.__doc__ = "strict CuPy stand-in (tests/strict_cupy.py)"
    cp.transfers = t
    cp.ndarray = StrictArray

    def func(name, np_func):
        def f(*args, **kwargs):
            return _wrap(np_func(*_unwrap(args, name), **_unwrap(kwargs, name)), t)
        f.__name__ = name
        return f

    for name in FUNCTIONS:
        setattr(cp, name, func(name, getattr(np, name)))
    for name in DTYPES:
        setattr(cp, name, getattr(np, name))

    def array(obj, dtype=None, copy=True, **kwargs):
        if isinstance(obj, StrictArray):
            return _wrap(np.array(obj._a, dtype=dtype, copy=copy), t)
        a = np.array(obj, dtype=dtype, copy=True)
        t.h2d += 1
        t.h2d_bytes += a.nbytes
        t._note("h2d", a)
        return StrictArray(a, t)

    def asarray(a, dtype=None, order=None, *, blocking=False):
        if isinstance(a, StrictArray):
            return a if dtype is None or np.dtype(dtype) == a.dtype else StrictArray(a._a.astype(dtype), t)
        return array(a, dtype=dtype)

    def asnumpy(a, stream=None, order="C", out=None, *, blocking=True):
        if isinstance(a, StrictArray):
            return _to_host(a)
        return np.asarray(a, order=order)

    def get_array_module(*args):
        return cp if any(isinstance(a, StrictArray) for a in args) else np

    cp.array, cp.asarray, cp.asnumpy, cp.get_array_module = array, asarray, asnumpy, get_array_module

    fft = types.ModuleType("cupy.fft")
    for name in ("rfftn", "irfftn", "fftn", "ifftn", "rfft", "irfft", "fft", "ifft", "fftfreq", "rfftfreq"):
        setattr(fft, name, func(f"fft.{name}", getattr(np.fft, name)))
    cp.fft = fft
    linalg = types.ModuleType("cupy.linalg")
    for name in ("norm", "cholesky", "solve", "eigh"):
        setattr(linalg, name, func(f"linalg.{name}", getattr(np.linalg, name)))
    cp.linalg = linalg

    class Event:  # cupy.cuda.Event: host wall clock here (the stand-in has no device time)
        def __init__(self, *args, **kwargs):
            self.t = None

        def record(self, stream=None):
            self.t = time.perf_counter()

        def synchronize(self):
            pass

    class MemoryPool:  # cupy.cuda.MemoryPool: the stand-in allocates on the host, so it holds nothing
        def used_bytes(self):
            return 0

        def total_bytes(self):
            return 0

        def free_all_blocks(self, stream=None):
            pass

    pool = MemoryPool()
    cp.get_default_memory_pool = lambda: pool
    runtime = types.SimpleNamespace(getDeviceCount=lambda: 1, memGetInfo=lambda: (0, 0),
                                    getDeviceProperties=lambda d: {"name": b"strict CuPy stand-in (host)"})
    cp.cuda = types.SimpleNamespace(
        runtime=runtime, Event=Event, get_elapsed_time=lambda a, b: 1e3 * (b.t - a.t),
        Device=lambda d=0: types.SimpleNamespace(synchronize=lambda: None, id=d))

    cpx = types.ModuleType("cupyx")

    def scatter_add(a, slices, value):
        if not isinstance(a, StrictArray):
            raise TypeError("cupyx.scatter_add needs a device array")
        np.add.at(a._a, _index(slices), value._a if isinstance(value, StrictArray) else _unwrap(value, "scatter_add"))

    cpx.scatter_add = scatter_add
    return cp, cpx


def install(monkeypatch, transfers: Transfers | None = None):
    """Put the stand-in in ``sys.modules`` as ``cupy`` and ``cupyx`` for one test -> the cupy module."""
    cp, cpx = make_modules(transfers)
    monkeypatch.setitem(sys.modules, "cupy", cp)
    monkeypatch.setitem(sys.modules, "cupyx", cpx)
    return cp
