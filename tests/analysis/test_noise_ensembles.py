"""vesicle_core.analysis.noise_ensembles on synthetic ensembles whose answers are known."""

import math

import numpy as np
import pytest

from vesicle_core.analysis import noise_ensembles as NE
from vesicle_core.errors import ConfigError

S5 = np.array([227.0, 553.0, 1106.5, 2224.0, 4448.0])


def test_point_stats_are_the_sample_mean_sd_and_standard_error():
    s = NE.point_stats([1.0, 2.0, 3.0, 4.0, np.nan])
    assert s.n == 4 and s.mean == 2.5
    assert s.sd == pytest.approx(math.sqrt(5.0 / 3.0)) and s.se == pytest.approx(s.sd / 2.0)
    one = NE.point_stats([7.0])
    assert one.mean == 7.0 and math.isnan(one.sd) and math.isnan(one.se)
    with pytest.raises(ConfigError, match="at least 1"):
        NE.point_stats([np.nan])


def test_bootstrap_exponent_recovers_an_exact_power_law():
    """Seeds scattered symmetrically about c S^b (equal relative offsets at every S) leave the means on the law."""
    off = np.array([-0.02, -0.01, 0.0, 0.01, 0.02])
    samples = [2.0 * s**0.43 * (1 + off) for s in S5]
    f = NE.bootstrap_exponent(S5, samples, n_boot=200)
    assert f.exponent == pytest.approx(0.43, abs=1e-12) and f.prefactor == pytest.approx(2.0, rel=1e-12)
    assert f.ci_low < 0.43 < f.ci_high and f.ci_high - f.ci_low < 0.02


@pytest.mark.parametrize("confidence, n_seeds", [(0.95, 8), (0.68, 8), (0.95, 4)])
def test_bootstrap_interval_covers_the_true_exponent_at_the_nominal_rate(confidence, n_seeds):
    """Over 300 synthetic ensembles (power law x (1 + 5% noise), five S), the interval holds the true exponent in
    a fraction within 3 binomial standard deviations of the confidence; an interval too narrow or too wide by a
    factor 1.3 misses that band (0.95 -> 0.86 / 0.99; 0.68 -> 0.55 / 0.81)."""
    rng = np.random.default_rng(12345)
    b, reps = 0.43, 300
    hits = 0
    for _ in range(reps):
        samples = [3.0 * s**b * (1 + 0.05 * rng.standard_normal(n_seeds)) for s in S5]
        f = NE.bootstrap_exponent(S5, samples, n_boot=300, confidence=confidence, rng=rng)
        hits += f.ci_low <= b <= f.ci_high
    band = 3 * math.sqrt(confidence * (1 - confidence) / reps)
    assert abs(hits / reps - confidence) < band, (hits / reps, confidence, band)


def test_bootstrap_exponent_refuses_bad_input():
    with pytest.raises(ConfigError, match="two distinct S"):
        NE.bootstrap_exponent([553.0], [[1.0, 2.0]])
    with pytest.raises(ConfigError, match="at least 2"):
        NE.bootstrap_exponent([553.0, 2224.0], [[1.0, 2.0], [3.0]])
    with pytest.raises(ConfigError, match="confidence"):
        NE.bootstrap_exponent([553.0, 2224.0], [[1.0, 2.0], [3.0, 4.0]], confidence=1.5)


def test_kT_slope_is_the_change_per_decade_with_the_error_of_the_means():
    # means 10, 12, 14 at kT 0.01, 0.1, 1 with equal errors: slope 2 per decade, se = se_mean / sqrt(sum (x-xbar)^2)
    d = np.array([-1.0, 1.0])
    samples = [m + d for m in (10.0, 12.0, 14.0)]
    f = NE.kT_slope([0.01, 0.1, 1.0], samples)
    se_mean = 1.0  # sd sqrt(2), two seeds
    assert f.slope == pytest.approx(2.0) and f.intercept == pytest.approx(14.0)
    assert f.slope_se == pytest.approx(se_mean / math.sqrt(2.0)) and f.n_kT == 3
    two = NE.kT_slope([0.0405, 0.405], [10 + d, 9 + d])
    assert two.slope == pytest.approx(-1.0) and two.slope_se == pytest.approx(math.sqrt(2.0))
    with pytest.raises(ConfigError, match="two distinct kT"):
        NE.kT_slope([0.0405, 0.0405], [10 + d, 9 + d])


def test_kT_slope_error_matches_the_scatter_of_repeated_ensembles():
    rng = np.random.default_rng(7)
    kT = np.array([0.00405, 0.0405, 0.405])
    fits = [NE.kT_slope(kT, [20 - 1.5 * np.log10(k) + rng.standard_normal(8) for k in kT]) for _ in range(400)]
    slopes = np.array([f.slope for f in fits])
    assert abs(slopes.mean() + 1.5) < 4 * slopes.std() / math.sqrt(400)
    assert np.median([f.slope_se for f in fits]) == pytest.approx(slopes.std(), rel=0.15)


def test_excess_and_its_delta_method_error():
    e = NE.excess([11.0, 13.0], [10.0, 10.0, 10.0])
    assert e.excess == pytest.approx(0.2) and e.se == pytest.approx(1.2 * 1.0 / 12.0)
    det = NE.excess([12.0], [10.0])
    assert det.excess == pytest.approx(0.2) and det.se == 0.0
    with pytest.raises(ConfigError, match="reference mean"):
        NE.excess([1.0, 2.0], [0.0, 0.0])


def test_convergence_check_by_relative_difference_or_standard_errors():
    fine = np.array([20.0, 21.0, 19.0, 20.0])
    assert NE.converged(fine * 1.02, fine).met                         # 2% apart: < 3%
    far = NE.converged(fine * 1.10, fine)                               # 10% apart, tight ensembles: not met
    assert not far.met and far.rel_diff == pytest.approx(0.10)
    noisy = np.array([15.0, 25.0, 18.0, 26.0])                          # mean 21, se ~2.6: 5% apart is < 2 se
    c = NE.converged(noisy, fine)
    assert c.met and abs(c.rel_diff) > 0.03 and abs(c.diff) < 2 * c.se_diff
