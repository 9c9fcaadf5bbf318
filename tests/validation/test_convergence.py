"""The ladder's extrapolation and exponent helpers against exact cases."""

import math

import numpy as np
import pytest

from vesicle_core.errors import ConfigError
from vesicle_core.validation.convergence import extrapolate, two_point_exponent, verdict


def test_extrapolation_recovers_an_exact_h2_law():
    h = np.array([5 / 64, 5 / 128, 5 / 192, 5 / 256])
    y = 28.0 - 900.0 * h**2
    e = extrapolate(h, y, order=2)
    assert e["n"] == 3 and math.isclose(e["value"], 28.0, rel_tol=1e-12)
    assert math.isclose(e["slope"], -900.0, rel_tol=1e-9)
    assert e["high"] - e["low"] < 1e-9  # no residual, no interval width


def test_extrapolation_interval_covers_noisy_truth():
    rng = np.random.default_rng(1)
    h = np.linspace(0.01, 0.05, 6)
    hits = 0
    for _ in range(200):
        y = 20.0 + 50.0 * h + rng.normal(0, 0.1, h.size)
        e = extrapolate(h, y, order=1, n_finest=6)
        hits += e["low"] <= 20.0 <= e["high"]
    assert 0.88 <= hits / 200 <= 0.99  # a 95% interval, checked by coverage


def test_extrapolation_with_two_rungs_has_no_interval():
    e = extrapolate([0.02, 0.04], [10.0, 9.0], order=1)
    assert math.isclose(e["value"], 11.0) and math.isnan(e["low"])


def test_two_point_exponent_and_verdict():
    assert math.isclose(two_point_exponent(553, 15.0, 2224, 15.0 * (2224 / 553) ** 0.39), 0.39)
    assert math.isnan(two_point_exponent(553, 0.0, 2224, 3.0))
    assert verdict(26.0, 28.0) == "within" and verdict(20.0, 28.0) == "below" and verdict(33.0, 28.0) == "above"
    assert verdict(20.0, 28.0, low=18.0, high=26.0) == "within"
    assert verdict(float("nan"), 28.0) == "n/a"


def test_bad_input_names_the_argument():
    with pytest.raises(ConfigError, match="order"):
        extrapolate([0.1, 0.2, 0.3], [1, 2, 3], order=0)
    with pytest.raises(ConfigError, match="h and y"):
        extrapolate([0.1, 0.2], [1, 2, 3])
