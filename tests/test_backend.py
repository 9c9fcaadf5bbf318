"""Backend selection, real FFTs and scatter-add (the primitives of eqs. 19-20 and 28)."""

import numpy as np
import pytest

from vesicle_core import backend as bk
from vesicle_core.backend import Backend, cupy_available, get_backend
from vesicle_core.errors import ConfigError

CPU_LIBS = ["scipy"] + (["pyfftw"] if bk._import_pyfftw() is not None else [])


def test_numpy_default():
    be = get_backend()
    assert isinstance(be, Backend)
    assert be.name == "numpy" and be.xp is np
    assert be.dtype == np.float64 and be.complex_dtype == np.complex128
    assert be.fft_workers == 1


def test_auto_without_gpu_falls_back_to_numpy():
    be = get_backend("auto")
    if cupy_available():
        assert be.name == "cupy"
    else:
        assert be.name == "numpy" and be.xp is np


def test_float32_option():
    be = get_backend(dtype="float32")
    assert be.dtype == np.float32 and be.complex_dtype == np.complex64
    a = np.random.default_rng(0).standard_normal((3, 8, 8, 8))
    A = be.rfftn(a, (1, 2, 3))
    assert A.dtype == np.complex64
    back = be.irfftn(A, (8, 8, 8), (1, 2, 3))
    assert back.dtype == np.float32
    np.testing.assert_allclose(back, a, atol=1e-5)


@pytest.mark.parametrize(
    "kwargs, word",
    [
        (dict(name="torch"), "backend name"),
        (dict(name=3), "backend name"),
        (dict(dtype="float16"), "dtype"),
        (dict(dtype="complex128"), "dtype"),
        (dict(dtype="nonsense"), "dtype"),
        (dict(fft_workers=0), "fft_workers"),
        (dict(fft_workers=1.5), "fft_workers"),
        (dict(fft_library="mkl"), "fft_library"),
        (dict(fft_planner="FFTW_FAST"), "fft_planner"),
    ],
)
def test_invalid_arguments_raise_config_error(kwargs, word):
    with pytest.raises(ConfigError) as exc:
        get_backend(**kwargs)
    msg = str(exc.value)
    assert word in msg
    # the message lists the allowed values (or the allowed range)
    assert ("numpy" in msg) or ("float64" in msg) or (">= 1" in msg) or ("scipy" in msg) or ("FFTW_" in msg)


def test_cupy_name_without_cupy_is_config_error():
    if cupy_available():
        pytest.skip("a GPU is available")
    with pytest.raises(ConfigError):
        get_backend("cupy")


def test_missing_pyfftw_falls_back_cleanly(monkeypatch):
    monkeypatch.setattr(bk, "_import_pyfftw", lambda: None)
    assert get_backend("numpy").fft_library == "scipy"
    with pytest.raises(ConfigError, match="pyfftw"):
        get_backend("numpy", fft_library="pyfftw")


@pytest.mark.parametrize("lib", CPU_LIBS)
@pytest.mark.parametrize("workers", [1, 2])
def test_fft_matches_numpy(lib, workers):
    be = get_backend(fft_library=lib, fft_workers=workers)
    rng = np.random.default_rng(1)
    a = rng.standard_normal((3, 8, 10, 12))
    a_copy = a.copy()
    A = be.rfftn(a, (1, 2, 3))
    np.testing.assert_allclose(A, np.fft.rfftn(a, axes=(1, 2, 3)), rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(a, a_copy)  # forward preserves its input
    A_copy = A.copy()
    back = be.irfftn(A, (8, 10, 12), (1, 2, 3))
    np.testing.assert_allclose(back, a, atol=1e-13)
    np.testing.assert_array_equal(A, A_copy)  # overwrite_x=False preserves the input
    unscaled = be.irfftn(A, (8, 10, 12), (1, 2, 3), norm="forward")
    np.testing.assert_allclose(unscaled, a * (8 * 10 * 12), atol=1e-10)


@pytest.mark.parametrize("lib", CPU_LIBS)
def test_fft_out_and_overwrite(lib):
    be = get_backend(fft_library=lib)
    rng = np.random.default_rng(2)
    a = rng.standard_normal((3, 8, 8, 8))
    out_c = be.empty((3, 8, 8, 5), be.complex_dtype)
    res = be.rfftn(a, (1, 2, 3), out=out_c)
    assert res is out_c
    out_r = np.empty((3, 8, 8, 8))  # plain NumPy buffer (maybe not SIMD-aligned): still filled
    res2 = be.irfftn(out_c, (8, 8, 8), (1, 2, 3), out=out_r, overwrite_x=True)
    assert res2 is out_r
    np.testing.assert_allclose(out_r, a, atol=1e-13)
    # strided (non-contiguous) input and repeated calls do not corrupt anything
    big = rng.standard_normal((3, 8, 8, 16))
    view = big[..., ::2]
    np.testing.assert_allclose(be.rfftn(view, (1, 2, 3)), np.fft.rfftn(view, axes=(1, 2, 3)), atol=1e-12)
    np.testing.assert_allclose(be.rfftn(a, (1, 2, 3)), np.fft.rfftn(a, axes=(1, 2, 3)), atol=1e-12)


def test_fft_norm_validation():
    be = get_backend()
    with pytest.raises(ConfigError):
        be.irfftn(np.zeros((4, 4, 3), complex), (4, 4, 4), (0, 1, 2), norm="ortho2")


def test_scatter_add_accumulates_duplicates():
    be = get_backend()
    out = np.zeros(10)
    idx = np.array([1, 3, 1, 9, 3, 1])
    vals = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    be.scatter_add(out, idx, vals)
    expected = np.zeros(10)
    for i, v in zip(idx, vals):
        expected[i] += v
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(be.bincount(idx, vals, 10), expected)


def test_asarray_asnumpy_roundtrip():
    be = get_backend()
    a = np.arange(6.0)
    assert be.asarray(a) is a
    np.testing.assert_array_equal(be.asnumpy(be.asarray(a)), a)


def test_backend_module_does_not_import_cupy_eagerly():
    import sys

    if "cupy" in sys.modules:
        pytest.skip("cupy already imported by something else")
    get_backend("numpy")
    assert "cupy" not in sys.modules


# ------------------------------------------------------------------ GPU (skipped without CuPy/device)
@pytest.mark.gpu
def test_cupy_backend_roundtrip():
    cupy = pytest.importorskip("cupy")
    if not cupy_available():
        pytest.skip("no CUDA device")
    be = get_backend("cupy")
    assert be.name == "cupy" and be.xp is cupy
    a = np.random.default_rng(3).standard_normal((3, 8, 8, 8))
    A = be.rfftn(be.asarray(a), (1, 2, 3))
    back = be.asnumpy(be.irfftn(A, (8, 8, 8), (1, 2, 3)))
    np.testing.assert_allclose(back, a, atol=1e-12)
    out = be.xp.zeros(10)
    be.scatter_add(out, be.asarray(np.array([1, 1, 2])), be.asarray(np.array([1.0, 2.0, 3.0])))
    np.testing.assert_array_equal(be.asnumpy(out)[:3], [0.0, 3.0, 3.0])


@pytest.mark.parametrize("lib", CPU_LIBS)
def test_plan_reuse_never_writes_into_earlier_arrays(lib):
    """pyFFTW's __call__ would copy unaligned input into the array bound by an earlier call;
    the backend must never touch a caller's array other than ``out``."""
    be = get_backend(fft_library=lib)
    rng = np.random.default_rng(4)
    a = be.empty((3, 8, 8, 8))
    a[...] = rng.standard_normal(a.shape)
    a_keep = a.copy()
    be.rfftn(a, (1, 2, 3))
    raw = np.empty(3 * 512 + 1)[1:].reshape(3, 8, 8, 8)  # deliberately misaligned by 8 bytes
    raw[...] = rng.standard_normal(raw.shape)
    B = be.rfftn(raw, (1, 2, 3))
    np.testing.assert_array_equal(a, a_keep)
    np.testing.assert_allclose(B, np.fft.rfftn(raw, axes=(1, 2, 3)), atol=1e-12)


def test_float32_stays_single_precision_with_scipy_fft():
    be = get_backend(dtype="float32", fft_library="scipy")
    a = np.random.default_rng(1).standard_normal((3, 8, 8, 8))  # float64 input
    A = be.rfftn(a, (1, 2, 3))
    assert A.dtype == np.complex64
    assert np.allclose(be.irfftn(A, (8, 8, 8), (1, 2, 3)), a, atol=1e-5)
