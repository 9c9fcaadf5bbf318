"""t_* between the frames (harmonics.t_star_between_frames): on a synthetic Delta_2(t) with a known minimum, sampled
on frame grids shifted against it, the frame value jumps by a whole spacing while the fitted vertex stays within the
error a three-point parabola is known to make; the interpolation weights carry l_*(t) there."""

import math

import numpy as np
import pytest

from vesicle_core.analysis.harmonics import t_star_between_frames, t_star_index

H = 0.02  # the default job's frame spacing, output_every
T0 = 0.1937  # the minimum, between frames
C2, C3 = 20.0, 30.0  # Delta_2 = D0 + C2 (t - T0)^2 + C3 (t - T0)^3: asymmetric, steeper after the minimum


def _cubic(t):
    x = t - T0
    return 0.3 + C2 * x**2 + C3 * x**3


def _grid(shift, h=H, n=60):
    """Frames from before the reversal (t < 0) to past the minimum, offset by ``shift`` spacings."""
    return -0.1 + (np.arange(n) + shift) * h


def test_the_vertex_follows_the_minimum_while_the_frame_value_jumps():
    """For every shift of the frame grid the vertex is off by exactly what a parabola through three samples of a
    cubic makes, c3 (3 s^2 - h^2) / (2 c2 + 6 c3 s) with s the middle frame's offset from the minimum: at most
    ~ c3 h^2 / (2 c2) = 3e-4 here, 30x below half a spacing. The frame value meanwhile takes two values h apart."""
    frame, fitted = [], []
    bound = C3 * H**2 / (2 * C2 - 3 * C3 * H)  # |s| <= h/2 in the denominator
    for shift in np.linspace(0.0, 1.0, 21):
        t = _grid(shift)
        t_fit, idx, w = t_star_between_frames(t, _cubic(t))
        assert len(idx) == 3 and sum(w) == pytest.approx(1.0, abs=1e-12)
        assert max(abs(x) for x in w) <= 1.125 + 1e-12  # the vertex within h/2 of the middle frame
        s = t[idx[1]] - T0
        assert abs(s) <= 0.5 * H + 1e-12  # the sampled minimum is the frame nearest T0 (a mild asymmetry)
        exact = C3 * (3 * s**2 - H**2) / (2 * C2 + 6 * C3 * s)
        assert t_fit - T0 == pytest.approx(exact, rel=1e-9, abs=1e-13)
        assert abs(t_fit - T0) <= bound
        frame.append(t[t_star_index(t, _cubic(t))])
        fitted.append(t_fit)
    # the frame value's error sweeps +-h/2: it flips from one frame to the next as the grid passes the minimum
    err = np.array(frame) - T0
    assert err.max() > 0.45 * H and err.min() < -0.45 * H
    assert max(fitted) - min(fitted) < 2 * bound < 0.05 * H


def test_a_smooth_asymmetric_minimum_is_found_to_the_leading_order_error():
    """Delta_2 = exp(a x) + (a / b) exp(-b x), x = t - T0, minimum at x = 0, not a polynomial: the vertex error is
    the leading-order one, |f'''| h^2 / (2 f''), to within the next order (b h = 0.3 here: a factor 1.5)."""
    a, b = 5.0, 15.0

    def f(t):
        x = t - T0
        return np.exp(a * x) + (a / b) * np.exp(-b * x)

    lead = abs(a**3 - a * b**2) * H**2 / (2 * (a**2 + a * b))
    for shift in np.linspace(0.0, 1.0, 21):
        t = _grid(shift)
        t_fit, _, _ = t_star_between_frames(t, f(t))
        assert abs(t_fit - T0) <= 1.5 * lead < 0.005


def test_a_parabola_is_found_exactly_on_unequal_frames_and_the_weights_interpolate_it():
    """Frames unequally spaced (adaptive output, a stride): a parabolic Delta_2 gives its vertex to round-off, and
    the weights reproduce any quadratic l_*(t) there, also when a frame in between has no finite Delta_2."""
    t = np.array([-0.05, 0.0, 0.013, 0.05, 0.071, 0.1, 0.13, 0.2, 0.26])
    d = 1.0 + 7.0 * (t - 0.083) ** 2
    d[5] = np.nan  # skipped: the stencil takes the next finite frame
    t_fit, idx, w = t_star_between_frames(t, d)
    assert t_fit == pytest.approx(0.083, abs=1e-12)
    assert idx == (3, 4, 6)
    lt = 12.0 + 30.0 * t - 40.0 * t**2
    assert np.dot(w, lt[list(idx)]) == pytest.approx(12.0 + 30.0 * 0.083 - 40.0 * 0.083**2, rel=1e-12)


@pytest.mark.parametrize("where", ["first", "last"])
def test_a_minimum_at_an_end_of_the_record_keeps_the_frame_value(where):
    """No bracket, no fit: a Delta_2 still falling at the last frame, or rising from the reversal on, gives the
    frame value itself (weight 1 on it), never an extrapolation. Frames before the reversal do not bracket it."""
    t = np.linspace(-0.1, 0.3, 21)
    d = np.exp(-t) if where == "last" else np.exp(t)
    t_fit, idx, w = t_star_between_frames(t, d)
    i = t_star_index(t, d)
    assert (t_fit, idx, w) == (t[i], (i,), (1.0,))
    assert t_fit == (0.3 if where == "last" else 0.0)


def test_no_frame_after_the_reversal():
    t_fit, idx, w = t_star_between_frames([-0.2, -0.1], [1.0, 0.5])
    assert math.isnan(t_fit) and idx == () and w == ()


def test_a_flat_minimum_gives_the_middle_of_the_tie():
    t = np.array([0.0, 0.1, 0.2, 0.3])
    t_fit, _, _ = t_star_between_frames(t, np.array([2.0, 1.0, 1.0, 2.0]))
    assert t_fit == pytest.approx(0.15, abs=1e-12)


def test_spectra_report_the_fit_beside_the_frame_values():
    """spectra._between_frames: l_*(t) by the same parabola where the minimum is bracketed; the frame values, with
    the reason in the method, at an end of the record or where a neighbour has no l_*."""
    from vesicle_core.analysis.spectra import _between_frames

    t = _grid(0.3)
    lt = 10.0 + 50.0 * t  # l_* still rising at t_*
    frame = {"t_star": float(t[t_star_index(t, _cubic(t))]), "l_star": math.nan}
    frame["l_star"] = float(lt[t_star_index(t, _cubic(t))])
    out = _between_frames(t, _cubic(t), lt, frame)
    assert out["t_star_fit_method"] == "quadratic"
    assert out["l_star_fit"] == pytest.approx(10.0 + 50.0 * out["t_star_fit"], rel=1e-12)  # exact for a line
    assert out["l_star_fit"] != frame["l_star"]
    lt_gap = lt.copy()
    lt_gap[t_star_index(t, _cubic(t)) + 1] = np.nan
    out = _between_frames(t, _cubic(t), lt_gap, frame)
    assert (out["t_star_fit"], out["l_star_fit"]) == (frame["t_star"], frame["l_star"])
    assert out["t_star_fit_method"] == "frame (no l_* at a neighbour)"
    out = _between_frames(t, np.exp(-t), lt, {"t_star": t[-1], "l_star": lt[-1]})
    assert out["t_star_fit_method"] == "frame (minimum at an end of the record)" and out["l_star_fit"] == lt[-1]


def test_the_power_law_fits_use_the_values_between_the_frames():
    """sweep_fit_dataset fits l_star_fit where a spectra file has it (exponent 0.4 exactly here, while the frame
    values carry a made-up jitter), keeps the frame values beside it, and falls back to them without."""
    import xarray as xr

    from vesicle_core.analysis.sweep_fits import sweep_fit_dataset

    t = np.linspace(0.0, 1.0, 51)
    S_all = (227.0, 553.0, 1106.5, 2224.0)

    def spectra(S, i, with_fit):
        ds = xr.Dataset({"sigma": ("time", -100.0 * (1 + t) ** -0.8), "face_tension_mean": ("time", np.zeros(51)),
                         "l_star": ((), 2.0 * S**0.4 * (1 + 0.05 * (-1) ** i)), "t_star": ((), 0.2 + 0.02 * i)},
                        coords={"time": t}, attrs={"delta": 0.116, "S": S, "N": 32, "case_id": f"c{i}"})
        if with_fit:
            ds["l_star_fit"], ds["t_star_fit"] = ((), 2.0 * S**0.4), ((), 0.21)
        return ds

    fit = sweep_fit_dataset([spectra(S, i, True) for i, S in enumerate(S_all)])
    assert float(fit.l_star_exponent[0]) == pytest.approx(0.4, rel=1e-9)
    np.testing.assert_allclose(fit.l_star_frame.values, [2.0 * S**0.4 * (1 + 0.05 * (-1) ** i)
                                                         for i, S in enumerate(S_all)])
    np.testing.assert_allclose(fit.t_star.values, 0.21)
    old = sweep_fit_dataset([spectra(S, i, False) for i, S in enumerate(S_all)])
    np.testing.assert_array_equal(old.l_star.values, old.l_star_frame.values)
    assert float(old.l_star_exponent[0]) != pytest.approx(0.4, rel=1e-3)
