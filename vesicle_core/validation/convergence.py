"""Resolution ladder (docs/validation.md): l_* against the grid spacing h = L/N, extrapolated to h -> 0.

The rule below was fixed before any comparison with the paper's numbers, from the mode-relaxation measurement
alone (docs/history/solver.md): the IBM relaxes (and grows) a mode l at exp(-(l h / a)^2) of its true rate, so for
resolved modes the leading error is ~ (l h / a)^2 and the wrinkle number converges like h^2.

* :func:`extrapolate` fits y = y_0 + c h^p by least squares over the ``n_finest`` finest rungs (default 3) and
  returns y_0 with its Student-t interval (n - 2 degrees of freedom). p = 2 is the primary model; p = 1 is
  reported beside it as the model uncertainty (if the two disagree, the rungs are not yet in the asymptotic range).
* :func:`two_point_exponent` is b = ln(l_2 / l_1) / ln(S_2 / S_1), the exponent a pair of S values implies.
* :func:`verdict` compares a value (and optionally its interval) with a published one at a relative tolerance.

Pure functions on plain numbers; the report (validation.py) reads them from the datasets.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError, check_range


def extrapolate(h, y, *, order=2.0, n_finest=3, confidence=0.95) -> dict:
    """y_0 of y = y_0 + c h^order over the n_finest smallest h; keys value, low, high, slope, n, order."""
    from scipy import stats

    h = np.asarray(h, dtype=float)
    y = np.asarray(y, dtype=float)
    if h.shape != y.shape or h.ndim != 1:
        raise ConfigError(f"h and y must be 1-D of equal length, got {h.shape} and {y.shape}")
    check_range("order", order, 0.0, 10.0, lo_open=True)
    check_range("confidence", confidence, 0.0, 1.0, lo_open=True, hi_open=True)
    ok = np.isfinite(h) & np.isfinite(y) & (h > 0)
    h, y = h[ok], y[ok]
    n_finest = int(check_range("n_finest", n_finest, 2, None, integer=True))
    idx = np.argsort(h)[:n_finest]
    h, y = h[idx], y[idx]
    n = len(h)
    out = {"value": math.nan, "low": math.nan, "high": math.nan, "slope": math.nan, "n": n, "order": float(order)}
    if n < 2:
        return out
    x = h**order
    A = np.stack([np.ones(n), x], axis=1)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    out.update(value=float(coef[0]), slope=float(coef[1]))
    if n > 2:
        resid = y - A @ coef
        s2 = float(resid @ resid) / (n - 2)
        cov = s2 * np.linalg.inv(A.T @ A)
        half = stats.t.ppf(0.5 + confidence / 2, n - 2) * math.sqrt(cov[0, 0])
        out.update(low=out["value"] - half, high=out["value"] + half)
    return out


def two_point_exponent(S1, l1, S2, l2) -> float:
    """b with l ~ S^b through two points (NaN if a value is missing or not positive)."""
    vals = [float(v) for v in (S1, l1, S2, l2)]
    if not all(math.isfinite(v) and v > 0 for v in vals) or vals[0] == vals[2]:
        return math.nan
    return math.log(vals[3] / vals[1]) / math.log(vals[2] / vals[0])


def verdict(value, reference, *, rel_tol=0.10, low=None, high=None) -> str:
    """'within' if value is within rel_tol of reference (or the interval [low, high] reaches the band), else
    'below'/'above'; 'n/a' if a number is missing."""
    if reference is None or not all(math.isfinite(float(v)) for v in (value, reference)):
        return "n/a"
    lo_band, hi_band = reference * (1 - rel_tol), reference * (1 + rel_tol)
    lo = value if low is None or not math.isfinite(low) else low
    hi = value if high is None or not math.isfinite(high) else high
    if hi < lo_band:
        return "below"
    if lo > hi_band:
        return "above"
    return "within"
