"""Backend selection, real FFTs and scatter-add (the primitives of eqs. 19-20 and 28)."""

import numpy as np
import pytest

from vesicle_core.errors import ConfigError
from vesicle_core.solver import backend as bk
from vesicle_core.solver.backend import Backend, cupy_available, get_backend

CPU_LIBS = ["scipy"] + (["pyfftw"] if bk._import_pyfftw() is not None else [])
# "numpy": the FFTs go through xp.fft, the code path of the CuPy backend (numpy.fft on the CPU)
ALL_CPU_LIBS = CPU_LIBS + ["numpy"]


def _dft_rfftn(a, axes):
    """Unnormalised real-to-complex DFT by explicit matrices exp(-2 pi i j k / n) (independent of any FFT)."""
    out = a.astype(complex)
    for ax in axes:
        n = a.shape[ax]
        j = np.arange(n)
        W = np.exp(-2j * np.pi * np.outer(j, j) / n)
        out = np.moveaxis(np.tensordot(W, np.moveaxis(out, ax, 0), axes=(1, 0)), 0, ax)
    last = axes[-1]
    return np.take(out, np.arange(a.shape[last] // 2 + 1), axis=last)


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


@pytest.mark.parametrize("lib", ALL_CPU_LIBS)
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


@pytest.mark.parametrize("lib", ALL_CPU_LIBS)
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
    for i, v in zip(idx, vals, strict=True):
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


@pytest.mark.parametrize("lib", ALL_CPU_LIBS)
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


@pytest.mark.parametrize("lib", ["scipy", "numpy"])
def test_float32_stays_single_precision_without_fftw(lib):
    be = get_backend(dtype="float32", fft_library=lib)
    a = np.random.default_rng(1).standard_normal((3, 8, 8, 8))  # float64 input
    A = be.rfftn(a, (1, 2, 3))
    assert A.dtype == np.complex64
    assert np.allclose(be.irfftn(A, (8, 8, 8), (1, 2, 3)), a, atol=1e-5)


# ------------------------------------------------------------------ the GPU FFT path (xp.fft) on the CPU
def test_xp_fft_path_is_opt_in():
    assert not get_backend().uses_xp_fft  # 'auto' never picks numpy.fft
    be = get_backend(fft_library="numpy")
    assert be.name == "numpy" and be.fft_library == "numpy" and be.uses_xp_fft and not be.is_gpu


@pytest.mark.parametrize("lib", ALL_CPU_LIBS)
def test_fft_matches_explicit_dft(lib):
    be = get_backend(fft_library=lib)
    a = np.random.default_rng(5).standard_normal((3, 4, 6, 8))
    ref = _dft_rfftn(a, (1, 2, 3))
    A = be.rfftn(a, (1, 2, 3))
    assert np.abs(A - ref).max() < 1e-12 * np.abs(ref).max()
    back = be.irfftn(A.copy(), (4, 6, 8), (1, 2, 3), norm="forward")
    np.testing.assert_allclose(back, a * (4 * 6 * 8), rtol=0, atol=1e-12 * 4 * 6 * 8)


def test_gpu_named_backend_takes_the_xp_fft_branch():
    """With name 'cupy' (is_gpu) the FFTs take the xp.fft branch whatever fft_library says; holding NumPy as
    xp, that branch runs here exactly as on a GPU, and must give the DFT."""
    import dataclasses

    fake = dataclasses.replace(get_backend(fft_library="scipy"), name="cupy")
    assert fake.is_gpu and fake.uses_xp_fft
    a = np.random.default_rng(6).standard_normal((3, 4, 6, 8))
    ref = _dft_rfftn(a, (1, 2, 3))
    out = fake.empty((3, 4, 6, 5), fake.complex_dtype)
    assert fake.rfftn(a, (1, 2, 3), out=out) is out
    assert np.abs(out - ref).max() < 1e-12 * np.abs(ref).max()
    np.testing.assert_allclose(fake.irfftn(out, (4, 6, 8), (1, 2, 3)), a, rtol=0, atol=1e-13)


# --------------------------------------------------------------------------- FFTW wisdom on disk
needs_pyfftw = pytest.mark.skipif(bk._import_pyfftw() is None, reason="pyFFTW not installed")


def _measured_rfft(n=12):
    be = get_backend("numpy", dtype="float32", fft_library="pyfftw", fft_planner="FFTW_MEASURE")
    a = np.random.default_rng(0).standard_normal((3, n, n, n)).astype(np.float32)
    return be.rfftn(a, axes=(1, 2, 3))


def _wisdom_only_plan(n=12):
    """Plan the same transform from wisdom alone: FFTW raises RuntimeError when it has none for it."""
    import pyfftw

    a = pyfftw.empty_aligned((3, n, n, n), dtype=np.float32)
    b = pyfftw.empty_aligned((3, n, n, n // 2 + 1), dtype=np.complex64)
    return pyfftw.FFTW(a, b, axes=(1, 2, 3), flags=("FFTW_MEASURE", "FFTW_WISDOM_ONLY"), threads=1)


def test_wisdom_path_from_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(bk.WISDOM_ENV, str(tmp_path / "w.json"))
    assert bk.fftw_wisdom_path() == tmp_path / "w.json"
    for off in ("off", "none", "0", ""):
        monkeypatch.setenv(bk.WISDOM_ENV, off)
        assert bk.fftw_wisdom_path() is None
    monkeypatch.delenv(bk.WISDOM_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert bk.fftw_wisdom_path() == tmp_path / "vesicle-wrinkling" / "fftw-wisdom.json"


@needs_pyfftw
def test_measured_plan_is_stored_and_reused_by_a_later_process(monkeypatch, tmp_path):
    """A measured plan lands in the wisdom file; a process that starts without wisdom (forget_wisdom) gets the
    same plan back from the file alone, which is what makes repeated 256^3 runs identical bit for bit."""
    import pyfftw

    path = tmp_path / "cache" / "w.json"
    monkeypatch.setenv(bk.WISDOM_ENV, str(path))
    pyfftw.forget_wisdom()
    first = _measured_rfft()
    assert path.exists() and len(bk._read_wisdom(path)) == 3
    pyfftw.forget_wisdom()
    with pytest.raises(RuntimeError):
        _wisdom_only_plan()  # nothing in memory any more: the plan below can only come from the file
    with bk.persistent_wisdom(pyfftw):
        _wisdom_only_plan()
    pyfftw.forget_wisdom()
    np.testing.assert_array_equal(_measured_rfft(), first)


@needs_pyfftw
def test_estimated_plans_and_disabled_wisdom_write_nothing(monkeypatch, tmp_path):
    path = tmp_path / "w.json"
    monkeypatch.setenv(bk.WISDOM_ENV, str(path))
    be = get_backend("numpy", dtype="float32", fft_library="pyfftw", fft_planner="FFTW_ESTIMATE")
    be.rfftn(np.ones((3, 8, 8, 8), np.float32), axes=(1, 2, 3))
    assert not path.exists()
    monkeypatch.setenv(bk.WISDOM_ENV, "off")
    _measured_rfft()
    assert not path.exists()


@needs_pyfftw
def test_bad_wisdom_cache_warns_and_never_stops_a_run(monkeypatch, tmp_path, caplog):
    path = tmp_path / "w.json"
    path.write_text("{not json")
    monkeypatch.setenv(bk.WISDOM_ENV, str(path))
    with caplog.at_level("WARNING", logger="vesicle_core.solver.backend"):
        ref = _measured_rfft()
    assert "unreadable" in caplog.text
    assert len(bk._read_wisdom(path)) == 3  # rewritten whole
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv(bk.WISDOM_ENV, str(blocker / "w.json"))  # its folder cannot be created
    caplog.clear()
    with caplog.at_level("WARNING", logger="vesicle_core.solver.backend"):
        np.testing.assert_allclose(_measured_rfft(), ref, rtol=1e-5, atol=1e-4)
    assert "not usable" in caplog.text
