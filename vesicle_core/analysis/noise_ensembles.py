r"""What thermal noise does to wrinkling, in numbers: statistics over the noise seeds of an ensemble.

A noisy run's l_* (eq. 31), l_peak and t_* are draws from a distribution; one sweep point (Delta, S, grid, kT) is
an ensemble of runs that differ only in their noise seed. This module reduces such ensembles:

* :func:`point_stats`: mean, sample standard deviation (ddof 1) and standard error sd / sqrt(n) of one point;
* :func:`bootstrap_exponent`: the exponent b of l_* ~ S^b (Fig. 4) with noise, fitted by least squares to
  log(mean l_*) against log S, and its percentile interval from a bootstrap over seeds: each replicate resamples
  the seeds *within* each S with replacement (the S values are the design, the seeds the sampling), recomputes the
  means and refits. The resampled deviations are inflated by sqrt(n / (n - 1)) (the "adjusted" bootstrap), so
  that a replicate mean's variance is s^2 / n, not the plain bootstrap's (n - 1) s^2 / n^2, which with 8 seeds
  makes a 95% interval cover ~93% of the time. The per-S variances are themselves estimates from a few seeds,
  so the interval is then stretched about b by t_df(q) / z(q), df of the slope's delta-method variance by
  Welch-Satterthwaite (a normal-theory bootstrap's intervals are otherwise too narrow with 4-8 seeds: measured
  coverage of a nominal 95% interval 92.9% over 2000 synthetic five-S, 8-seed ensembles before this step);
* :func:`kT_slope`: how l_* moves per decade of kT: the weighted least-squares slope of the per-kT means against
  log10 kT (weights 1 / se^2) and its standard error sqrt(1 / sum w (x - x_w)^2), the error of the means alone;
* :func:`excess`: the IBM's relative excess over a reference (the stochastic PA), mean_ibm / mean_ref - 1, with
  its standard error by the delta method, (1 + e) sqrt((se_ibm / mean_ibm)^2 + (se_ref / mean_ref)^2);
* :func:`converged`: the resolution check of a noisy point: two rungs' ensemble means differ by less than
  ``rel`` (3%) of the finer one's, or by less than ``n_se`` (2) standard errors of the difference.

Everything takes plain arrays (one per S, kT or rung, of per-seed values) and returns small dataclasses; the sweep's
dataset of these numbers is built by :mod:`vesicle_core.analysis.noise_tables`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm
from scipy.stats import t as student_t

from ..errors import ConfigError, check_range

__all__ = ["PointStats", "point_stats", "BootstrapExponent", "bootstrap_exponent", "KTSlope", "kT_slope",
           "Excess", "excess", "Convergence", "converged"]


def _values(name, v, min_n=1):
    a = np.asarray(v, dtype=float).ravel()
    a = a[np.isfinite(a)]
    if a.size < min_n:
        raise ConfigError(f"{name}: needs at least {min_n} finite per-seed value(s), got {a.size}")
    return a


@dataclass(frozen=True)
class PointStats:
    """One ensemble point: n seeds, mean, sample sd (NaN for n = 1) and standard error of the mean."""

    n: int
    mean: float
    sd: float
    se: float


def point_stats(values) -> PointStats:
    """Mean +- sd and the standard error over the finite per-seed ``values`` of one point."""
    a = _values("point_stats", values)
    sd = float(a.std(ddof=1)) if a.size > 1 else math.nan
    return PointStats(int(a.size), float(a.mean()), sd, sd / math.sqrt(a.size) if a.size > 1 else math.nan)


def _ols_slopes(x, Y):
    """Least-squares slopes and intercepts of each row of Y (..., k) against x (k,)."""
    xc = x - x.mean()
    b = (Y - Y.mean(axis=-1, keepdims=True)) @ xc / float(xc @ xc)
    return b, Y.mean(axis=-1) - b * x.mean()


@dataclass(frozen=True)
class BootstrapExponent:
    """b of y ~ c S^b from the per-S means, and its bootstrap percentile interval at ``confidence``."""

    exponent: float
    prefactor: float
    ci_low: float
    ci_high: float
    confidence: float
    n_boot: int
    n_S: int


def bootstrap_exponent(S, samples, *, n_boot=2000, confidence=0.95, rng=None) -> BootstrapExponent:
    """The exponent of the per-S means of ``samples`` (one array of per-seed values per S, >= 2 seeds each) against
    ``S`` (>= 2 distinct values), with its interval from ``n_boot`` resamplings of the seeds within each S (module
    docstring). ``rng``: a numpy Generator or seed (default: seed 0, so a rerun gives the same interval)."""
    S = np.asarray(S, dtype=float).ravel()
    if S.size != len(samples):
        raise ConfigError(f"bootstrap_exponent: {S.size} S values but {len(samples)} sample sets")
    if S.size < 2 or np.ptp(np.log(S)) <= 0 or np.any(S <= 0):
        raise ConfigError("bootstrap_exponent: needs at least two distinct S > 0")
    check_range("confidence", confidence, 0.0, 1.0, lo_open=True, hi_open=True)
    check_range("n_boot", n_boot, 10, None, integer=True)
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(0 if rng is None else rng)
    sets = [_values(f"samples at S = {s:g}", v, min_n=2) for s, v in zip(S, samples, strict=True)]
    if any(np.any(v <= 0) for v in sets):
        raise ConfigError("bootstrap_exponent: per-seed values must be > 0 (a power law in log-log)")
    x = np.log(S)
    means = np.array([v.mean() for v in sets])
    b, a = _ols_slopes(x, np.log(means))
    reps = np.empty((n_boot, S.size))
    for j, v in enumerate(sets):
        n = v.size
        dev = (v - v.mean()) * math.sqrt(n / (n - 1))
        reps[:, j] = v.mean() + dev[rng.integers(0, n, size=(n_boot, n))].mean(axis=1)
    # a replicate mean can only fall to <= 0 for values spread over more than their mean: refuse rather than clip
    if np.any(reps <= 0):
        raise ConfigError("bootstrap_exponent: a resampled mean is <= 0; the spread is too large for a log fit")
    bb, _ = _ols_slopes(x, np.log(reps))
    lo, hi = np.quantile(bb, [(1 - confidence) / 2, (1 + confidence) / 2])
    # the bootstrap's spread is a normal-theory one with the per-S variances taken as known; with a few seeds they
    # are estimates, so stretch the interval about b by t_df / z, df of the slope's variance by Welch-Satterthwaite
    xc = x - x.mean()
    v = (xc / float(xc @ xc)) ** 2 * np.array([u.var(ddof=1) / u.size / u.mean() ** 2 for u in sets])
    df = float(v.sum() ** 2 / np.sum(v**2 / np.array([u.size - 1 for u in sets]))) if v.sum() > 0 else math.inf
    q = (1 + confidence) / 2
    stretch = float(student_t.ppf(q, df) / norm.ppf(q)) if math.isfinite(df) else 1.0
    lo, hi = b - (b - lo) * stretch, b + (hi - b) * stretch
    return BootstrapExponent(float(b), float(math.exp(a)), float(lo), float(hi), float(confidence), int(n_boot),
                             int(S.size))


@dataclass(frozen=True)
class KTSlope:
    """d mean(l_*) / d log10(kT): the change of l_* per decade of kT, and its standard error."""

    slope: float
    slope_se: float
    intercept: float  # mean l_* at kT = 1 (log10 kT = 0) on the fitted line
    n_kT: int


def kT_slope(kT, samples) -> KTSlope:
    """Weighted least squares of the per-kT means against log10 kT, weights 1 / se^2 (module docstring); needs
    two or more distinct kT > 0 with >= 2 seeds each (two points give the exact line and the error of its ends)."""
    kT = np.asarray(kT, dtype=float).ravel()
    if kT.size != len(samples):
        raise ConfigError(f"kT_slope: {kT.size} kT values but {len(samples)} sample sets")
    if np.any(kT <= 0) or np.unique(kT).size < 2:
        raise ConfigError("kT_slope: needs at least two distinct kT > 0")
    stats = [point_stats(_values(f"samples at kT = {k:g}", v, min_n=2)) for k, v in zip(kT, samples, strict=True)]
    se = np.array([s.se for s in stats])
    if np.any(~(se > 0)):
        raise ConfigError("kT_slope: a point's standard error is 0 (identical seeds); the slope has no error")
    x, y, w = np.log10(kT), np.array([s.mean for s in stats]), 1.0 / se**2
    xw = float(np.sum(w * x) / np.sum(w))
    sxx = float(np.sum(w * (x - xw) ** 2))
    slope = float(np.sum(w * (x - xw) * y) / sxx)
    yw = float(np.sum(w * y) / np.sum(w))
    return KTSlope(slope, math.sqrt(1.0 / sxx), yw - slope * xw, int(kT.size))


@dataclass(frozen=True)
class Excess:
    """mean_ibm / mean_ref - 1 and its delta-method standard error."""

    excess: float
    se: float


def excess(ibm, reference) -> Excess:
    """The relative excess of the IBM's ensemble mean over the reference's (per-seed values of each; a single
    deterministic value counts with zero error)."""
    a, r = point_stats(ibm), point_stats(reference)
    if not r.mean > 0:
        raise ConfigError("excess: the reference mean must be > 0")
    ratio = a.mean / r.mean
    rel = [0.0 if s.n == 1 else s.se / s.mean for s in (a, r)]
    return Excess(ratio - 1.0, ratio * math.hypot(*rel))


@dataclass(frozen=True)
class Convergence:
    """Coarse against fine ensemble: relative difference (coarse / fine - 1), the difference of the means, its
    standard error, and whether the check is met."""

    rel_diff: float
    diff: float
    se_diff: float
    met: bool


def converged(coarse, fine, *, rel=0.03, n_se=2.0) -> Convergence:
    """The convergence check of issue 49: met when |mean_c - mean_f| < rel mean_f or < n_se se(mean_c - mean_f),
    se of the difference sqrt(se_c^2 + se_f^2) (both ensembles need >= 2 seeds)."""
    c, f = point_stats(_values("coarse", coarse, 2)), point_stats(_values("fine", fine, 2))
    d = c.mean - f.mean
    se = math.hypot(c.se, f.se)
    return Convergence(d / f.mean, d, se, bool(abs(d) < rel * abs(f.mean) or abs(d) < n_se * se))
