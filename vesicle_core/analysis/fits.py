"""Power-law fits with confidence intervals, and the algebraic decay of the tension in stage 2 (Sec. V.A).

Power laws
----------
:func:`fit_power_law` fits ``y = prefactor * x**exponent`` by ordinary least squares of ``ln y`` on ``ln x``
(``scipy.stats.linregress``).
Intervals are the classical Student-t intervals of simple linear regression with ``n - 2`` degrees of freedom,
``exponent +- t_{(1+c)/2, n-2} * stderr`` with ``stderr = sqrt(SSR / (n-2) / sum (ln x - mean ln x)^2)``; they
assume independent, homoscedastic errors in ``ln y`` (multiplicative noise in ``y``). Uses: l_* ~ S^b (Fig. 4),
|sigma| ~ t^-a (stage 2).

Tension stages (Sec. V.A, Fig. 3/5)
-----------------------------------
After the reversal the global tension drops to a negative plateau (stage 1, exponential growth of the wrinkles),
relaxes once that growth saturates, decays algebraically (stage 2), and finally recovers its positive equilibrium
value (stage 3). :func:`detect_tension_stages` finds the boundaries from sigma(t) alone with this rule:

1. ``t_sigma_min``: the time of the most negative tension (sigma_min < 0 is required).
2. ``t_recovery``: the first time after ``t_sigma_min`` with sigma >= 0 (NaN if the record ends first).
3. ``t_stage1_end``: the first time after ``t_sigma_min`` at which |sigma| <= (1 - plateau_drop) |sigma_min|,
   i.e. the tension has left its stage-1 plateau by more than ``plateau_drop`` (default 2 %).
4. Stage 2 is the *longest* window, measured in ln(t - t0), inside [t_stage1_end, t_recovery) over which
   ln|sigma| is a straight line of ln(t - t0) to within an rms residual ``rms_tol`` (default 0.01, i.e. 1 % in
   |sigma|) with at least ``min_points`` samples. The knee where the exponential growth saturates and the final
   plunge of |sigma| towards the zero crossing are both curved in log-log, so they are excluded automatically;
   no time scale has to be supplied. ``t_stage2_start`` / ``t_stage2_end`` are its first and last samples.
   (Window search is exhaustive over all pairs, on at most ``max_search`` samples evenly spread in ln t; the
   final fit uses every sample inside the window.)

Noisy data (simulations): ``rms_tol`` must exceed the rms noise of ln|sigma|, ``plateau_drop`` a few times it,
and ``smooth`` (odd number of samples of a running median, default 1 = none) should be set so that steps 1-3
see the plateau rather than single noisy samples; the fit itself always uses the raw samples. The reported
interval is the regression interval inside the detected window; the choice of window adds a systematic
uncertainty (on the PA's own sigma(t), varying rms_tol from 0.005 to 0.05 moves the exponent by ~ +-0.05).

:func:`tension_decay` then fits |sigma| = c (t - t0)^(-a) on the stage-2 window and returns ``a`` (positive
for a decay) with its interval. Time may be in any unit (the exponent does not depend on it); ``t0`` is the
reversal time (0 in the datasets of this package, whose ``time`` coordinate is gamma_dot (t - t0)).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..errors import ConfigError, check_range

__all__ = [
    "PowerLawFit",
    "fit_power_law",
    "TensionStages",
    "detect_tension_stages",
    "TensionDecayFit",
    "tension_decay",
    "local_decay_exponent",
]


def _as_1d(name, values):
    try:
        a = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be an array of numbers") from None
    if a.ndim != 1:
        a = a.ravel()
    return a


def _check_confidence(confidence):
    check_range("confidence", confidence, 0.0, 1.0, lo_open=True, hi_open=True)
    return float(confidence)


@dataclass(frozen=True)
class PowerLawFit:
    """Result of :func:`fit_power_law`: ``y = prefactor * x**exponent``.

    ``ci_low``/``ci_high`` bound the exponent at ``confidence``; ``prefactor_ci_low/high`` bound the prefactor
    (the interval of the log-log intercept, exponentiated). ``stderr`` is the standard error of the exponent,
    ``r2`` the coefficient of determination of the log-log regression, ``n`` the number of points.
    """

    exponent: float
    prefactor: float
    ci_low: float
    ci_high: float
    stderr: float
    n: int
    r2: float
    confidence: float = 0.95
    prefactor_ci_low: float = float("nan")
    prefactor_ci_high: float = float("nan")
    x_min: float = float("nan")
    x_max: float = float("nan")

    def predict(self, x):
        """prefactor * x**exponent."""
        return self.prefactor * np.asarray(x, dtype=float) ** self.exponent

    def contains(self, exponent) -> bool:
        """Whether ``exponent`` lies inside the confidence interval."""
        return bool(self.ci_low <= exponent <= self.ci_high)

    def as_dict(self) -> dict:
        return asdict(self)

    def to_dataset(self, prefix: str = ""):
        """Scalars as an xarray Dataset (names optionally prefixed), with units/long_name and method attrs."""
        import xarray as xr

        long = {
            "exponent": "power-law exponent b of y = c x^b",
            "prefactor": "prefactor c of y = c x^b",
            "ci_low": f"lower end of the {self.confidence:.0%} interval of b",
            "ci_high": f"upper end of the {self.confidence:.0%} interval of b",
            "stderr": "standard error of b",
            "n": "number of points",
            "r2": "coefficient of determination in log-log",
            "prefactor_ci_low": f"lower end of the {self.confidence:.0%} interval of c",
            "prefactor_ci_high": f"upper end of the {self.confidence:.0%} interval of c",
            "x_min": "smallest x used",
            "x_max": "largest x used",
        }
        data = {}
        for key, text in long.items():
            data[prefix + key] = xr.DataArray(getattr(self, key), attrs={"long_name": text, "units": "1"})
        return xr.Dataset(
            data,
            attrs={
                "model": "y = prefactor * x**exponent",
                "method": "ordinary least squares of ln y on ln x; Student-t intervals with n-2 dof",
                "confidence": self.confidence,
            },
        )


def fit_power_law(x, y, confidence: float = 0.95) -> PowerLawFit:
    """Fit ``y = c x^b`` by least squares in log-log with Student-t confidence intervals.

    Raises ConfigError for fewer than 3 points (no degree of freedom left for the interval), mismatched
    lengths, non-finite or non-positive values, or x values that are all equal.
    """
    confidence = _check_confidence(confidence)
    x = _as_1d("x", x)
    y = _as_1d("y", y)
    if x.shape != y.shape:
        raise ConfigError(f"x and y must have the same length, got {x.size} and {y.size}")
    n = x.size
    if n < 3:
        raise ConfigError(f"a power-law fit with a confidence interval needs at least 3 points, got {n}")
    for name, a in (("x", x), ("y", y)):
        if not np.all(np.isfinite(a)):
            raise ConfigError(f"{name} contains {np.count_nonzero(~np.isfinite(a))} non-finite value(s)")
        bad = np.flatnonzero(a <= 0)
        if bad.size:
            raise ConfigError(
                f"a power-law fit needs positive {name}; {bad.size} value(s) are <= 0 "
                f"(first at index {bad[0]}: {a[bad[0]]!r}); fit |{name}| or shift the data first"
            )
    from scipy import stats

    X = np.log(x)
    Y = np.log(y)
    xm = X.mean()
    sxx = float((X - xm) @ (X - xm))
    if not sxx > 0 or sxx < 1e-24 * max(1.0, float(X @ X)):
        raise ConfigError("all x values are equal: the exponent is undetermined")
    reg = stats.linregress(X, Y)
    b, a = float(reg.slope), float(reg.intercept)
    # standard errors from the residuals, as linregress defines them; its own stderr, sqrt((1 - r^2) syy / sxx / dof),
    # loses its digits as r -> 1 (1e-8 instead of 1e-16 on an exact power law)
    resid = Y - (a + b * X)
    dof = n - 2
    s2 = float(resid @ resid) / dof
    se_b = math.sqrt(s2 / sxx)
    se_a = se_b * math.sqrt(sxx / n + xm * xm)  # linregress's intercept_stderr
    tcrit = float(stats.t.ppf(0.5 * (1.0 + confidence), dof))  # Student-t, two-sided at `confidence`
    r2 = float(reg.rvalue) ** 2 if np.ptp(Y) > 0 else 1.0  # a constant y is fitted exactly (linregress: r = 0)
    return PowerLawFit(
        exponent=b,
        prefactor=math.exp(a),
        ci_low=b - tcrit * se_b,
        ci_high=b + tcrit * se_b,
        stderr=se_b,
        n=int(n),
        r2=float(r2),
        confidence=confidence,
        prefactor_ci_low=math.exp(a - tcrit * se_a),
        prefactor_ci_high=math.exp(a + tcrit * se_a),
        x_min=float(x.min()),
        x_max=float(x.max()),
    )


# --------------------------------------------------------------------------- tension stages


@dataclass(frozen=True)
class TensionStages:
    """Stage boundaries of a tension history found by :func:`detect_tension_stages` (times as given).

    ``i_stage2`` is the (start, stop) slice of sample indices of the stage-2 window (stop exclusive).
    """

    t0: float
    t_sigma_min: float
    sigma_min: float
    t_stage1_end: float
    t_stage2_start: float
    t_stage2_end: float
    t_recovery: float
    i_stage2: tuple
    plateau_drop: float
    rms_tol: float
    rms_stage2: float
    rule: str = (
        "stage 1 ends when |sigma| first drops below (1-plateau_drop)|sigma_min| after the most negative "
        "tension; stage 2 is the longest window in ln(t-t0) between that time and the first zero crossing "
        "(t_recovery) on which ln|sigma| is linear in ln(t-t0) within rms_tol"
    )

    def as_dict(self) -> dict:
        d = asdict(self)
        d["i_stage2"] = list(self.i_stage2)
        return d


def _window_search(x, y, min_points, rms_tol):
    """Longest window [i, j] (in x) whose straight-line fit has rms residual <= rms_tol. Returns (i, j, rms)."""
    m = x.size
    z = np.zeros(1)
    c1 = np.concatenate([z, np.cumsum(np.ones(m))])
    cx = np.concatenate([z, np.cumsum(x)])
    cy = np.concatenate([z, np.cumsum(y)])
    cxx = np.concatenate([z, np.cumsum(x * x)])
    cxy = np.concatenate([z, np.cumsum(x * y)])
    cyy = np.concatenate([z, np.cumsum(y * y)])
    i = np.arange(m)[:, None]
    j = np.arange(m)[None, :]
    valid = (j - i + 1) >= min_points

    def seg(c):
        return c[j + 1] - c[i]

    n = seg(c1)
    with np.errstate(invalid="ignore", divide="ignore"):
        sx, sy = seg(cx), seg(cy)
        sxx = seg(cxx) - sx * sx / n
        sxy = seg(cxy) - sx * sy / n
        syy = seg(cyy) - sy * sy / n
        ssr = np.where(sxx > 0, syy - sxy * sxy / np.where(sxx > 0, sxx, 1.0), np.inf)
        rms = np.sqrt(np.maximum(ssr, 0.0) / n)
    ok = valid & (rms <= rms_tol)
    if not ok.any():
        return None
    length = np.where(ok, x[None, :] - x[:, None], -np.inf)
    best = np.max(length)
    cand = ok & (length >= best - 1e-12 * max(1.0, abs(best)))
    bi, bj = divmod(int(np.argmin(np.where(cand, rms, np.inf))), m)
    return int(bi), int(bj), float(rms[bi, bj])


def _stage_samples(time, sigma, t0, plateau_drop, rms_tol, min_points, max_search, smooth):
    """time and sigma as float arrays after checking them and the rule's parameters (ConfigError otherwise)."""
    t = _as_1d("time", time)
    s = _as_1d("sigma", sigma)
    if t.shape != s.shape:
        raise ConfigError(f"time and sigma must have the same length, got {t.size} and {s.size}")
    check_range("min_points", min_points, 3, None, integer=True)
    check_range("plateau_drop", plateau_drop, 0.0, 1.0, lo_open=True, hi_open=True)
    check_range("rms_tol", rms_tol, 0.0, None, lo_open=True)
    check_range("max_search", max_search, 10, None, integer=True)
    check_range("smooth", smooth, 1, None, integer=True)
    if t.size < min_points + 2:
        raise ConfigError(f"need at least {min_points + 2} samples to find the tension stages, got {t.size}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(s))):
        raise ConfigError("time and sigma must be finite")
    if np.any(np.diff(t) <= 0):
        raise ConfigError("time must be strictly increasing")
    if not (t > t0).any():
        raise ConfigError(f"no samples after the reversal time t0 = {t0}")
    return t, s


def _stage1(t, sm, t0, plateau_drop):
    """Steps 1-3 of the rule (module docstring) on the (smoothed) tension ``sm``: the most negative tension, the
    recovery and the end of the stage-1 plateau. -> (i_min, sigma_min, i_recovery, t_recovery, i_stage1_end);
    i_recovery is len(t) when the record ends first."""
    idx_after = np.flatnonzero(t > t0)
    i_min = int(idx_after[np.argmin(sm[idx_after])])
    s_min = float(sm[i_min])
    if not s_min < 0:
        raise ConfigError("sigma is never negative after t0: there is no compression (wrinkling) stage to fit")
    pos = np.flatnonzero((np.arange(t.size) > i_min) & (sm >= 0))
    i_rec = int(pos[0]) if pos.size else t.size
    t_rec = float(t[i_rec]) if pos.size else float("nan")
    left = np.flatnonzero((np.arange(t.size) > i_min) & (np.arange(t.size) < i_rec)
                          & (np.abs(sm) <= (1.0 - plateau_drop) * abs(s_min)))
    if not left.size:
        raise ConfigError(
            f"the tension never leaves its stage-1 plateau by more than plateau_drop = {plateau_drop:g} "
            "before it recovers or the record ends"
        )
    return i_min, s_min, i_rec, t_rec, int(left[0])


def _stage2(t, s, t0, i1, i_rec, min_points, max_search, rms_tol):
    """Step 4 of the rule: the longest window in ln(t - t0) inside [i1, i_rec) on which ln|sigma| (raw samples)
    is a straight line within ``rms_tol``, searched on at most ``max_search`` samples evenly spread in ln t.
    -> (first, last) sample index and the rms residual of the fit on every sample of the window."""
    cand = np.arange(i1, i_rec)
    cand = cand[s[cand] < 0]
    if cand.size < min_points:
        raise ConfigError(
            f"only {cand.size} samples between the end of stage 1 and the recovery; need min_points = {min_points}"
        )
    x_all = np.log(t[cand] - t0)
    y_all = np.log(-s[cand])
    if cand.size > max_search:
        grid = np.linspace(x_all[0], x_all[-1], max_search)
        sub = np.unique(np.clip(np.searchsorted(x_all, grid), 0, cand.size - 1))
    else:
        sub = np.arange(cand.size)
    found = _window_search(x_all[sub], y_all[sub], min(min_points, sub.size), rms_tol)
    if found is None:
        raise ConfigError(
            f"no stage-2 window of {min_points} samples is a power law within rms_tol = {rms_tol:g}; "
            "increase rms_tol for noisy data"
        )
    bi, bj, _ = found
    a, b = int(cand[sub[bi]]), int(cand[sub[bj]])
    xs, ys = np.log(t[a:b + 1] - t0), np.log(-s[a:b + 1])
    coef = np.polyfit(xs, ys, 1)
    return a, b, float(np.sqrt(np.mean((ys - np.polyval(coef, xs)) ** 2)))


def detect_tension_stages(time, sigma, *, t0: float = 0.0, plateau_drop: float = 0.02, rms_tol: float = 0.01,
                          min_points: int = 5, max_search: int = 600, smooth: int = 1) -> TensionStages:
    """Find the three stages of a tension history sigma(t) (rule in the module docstring).

    time: strictly increasing sample times; sigma: tension at those times (any unit); t0: time of the flow
    reversal (the power law is in t - t0). Raises ConfigError if the tension is never negative, never leaves
    its plateau, or no stage-2 window of ``min_points`` samples is straight within ``rms_tol``.
    """
    t, s = _stage_samples(time, sigma, t0, plateau_drop, rms_tol, min_points, max_search, smooth)
    if smooth > 1:  # running median: locates the plateau and its exit in noisy data (the fit uses raw data)
        from scipy.ndimage import median_filter

        sm = median_filter(s, size=int(smooth), mode="nearest")
    else:
        sm = s
    i_min, s_min, i_rec, t_rec, i1 = _stage1(t, sm, t0, plateau_drop)
    a, b, rms = _stage2(t, s, t0, i1, i_rec, min_points, max_search, rms_tol)
    return TensionStages(
        t0=float(t0),
        t_sigma_min=float(t[i_min]),
        sigma_min=s_min,
        t_stage1_end=float(t[i1]),
        t_stage2_start=float(t[a]),
        t_stage2_end=float(t[b]),
        t_recovery=t_rec,
        i_stage2=(a, b + 1),
        plateau_drop=float(plateau_drop),
        rms_tol=float(rms_tol),
        rms_stage2=rms,
    )


@dataclass(frozen=True)
class TensionDecayFit:
    """|sigma| = c (t - t0)^(-exponent) in stage 2: ``exponent`` = a > 0 for a decay; ``fit`` is the raw
    log-log fit of |sigma| against t - t0 (its exponent is -a); ``stages`` the detected boundaries."""

    exponent: float
    ci_low: float
    ci_high: float
    fit: PowerLawFit
    stages: TensionStages

    def to_dataset(self):
        import xarray as xr

        ds = self.fit.to_dataset(prefix="loglog_")
        ds["exponent"] = xr.DataArray(self.exponent, attrs={
            "long_name": "stage-2 decay exponent a of |sigma| ~ (t - t0)^-a", "units": "1"})
        ds["ci_low"] = xr.DataArray(self.ci_low, attrs={
            "long_name": f"lower end of the {self.fit.confidence:.0%} interval of a", "units": "1"})
        ds["ci_high"] = xr.DataArray(self.ci_high, attrs={
            "long_name": f"upper end of the {self.fit.confidence:.0%} interval of a", "units": "1"})
        st = self.stages
        for key, text in (
            ("t_sigma_min", "time of the most negative tension"),
            ("sigma_min", "most negative tension"),
            ("t_stage1_end", "end of stage 1 (tension leaves its plateau)"),
            ("t_stage2_start", "first sample of the stage-2 fit window"),
            ("t_stage2_end", "last sample of the stage-2 fit window"),
            ("t_recovery", "first zero crossing of sigma after its minimum (NaN: none)"),
            ("rms_stage2", "rms residual of ln|sigma| in the stage-2 window"),
        ):
            units = "same as sigma" if key == "sigma_min" else ("1" if key == "rms_stage2" else "same as time")
            ds[key] = xr.DataArray(getattr(st, key), attrs={"long_name": text, "units": units})
        ds.attrs.update({
            "model": "|sigma| = c (t - t0)^(-exponent) in stage 2",
            "stage_rule": st.rule,
            "t0": st.t0,
            "plateau_drop": st.plateau_drop,
            "rms_tol": st.rms_tol,
        })
        return ds


def tension_decay(time, sigma, *, t0: float = 0.0, confidence: float = 0.95, plateau_drop: float = 0.02,
                  rms_tol: float = 0.01, min_points: int = 5, max_search: int = 600,
                  smooth: int = 1) -> TensionDecayFit:
    """Algebraic decay exponent of the tension in stage 2, |sigma| ~ (t - t0)^-a, with its interval.

    The stage-2 window is found by :func:`detect_tension_stages` (rule in the module docstring) and recorded
    in the result.
    """
    confidence = _check_confidence(confidence)
    st = detect_tension_stages(time, sigma, t0=t0, plateau_drop=plateau_drop, rms_tol=rms_tol,
                               min_points=min_points, max_search=max_search, smooth=smooth)
    t = _as_1d("time", time)
    s = _as_1d("sigma", sigma)
    a, b = st.i_stage2
    fit = fit_power_law(t[a:b] - t0, -s[a:b], confidence=confidence)
    return TensionDecayFit(exponent=-fit.exponent, ci_low=-fit.ci_high, ci_high=-fit.ci_low, fit=fit, stages=st)


# --------------------------------------------------------------------------- the local exponent
def local_decay_exponent(time, sigma, *, t0: float = 0.0) -> np.ndarray:
    """The local exponent a(t) = -d ln|sigma| / d ln(t - t0) at each sample (centred differences in ln t,
    one-sided at the ends): constant, and equal to the fitted ``a``, only where |sigma| is a true power law.
    A stage-2 fit over a window where a(t) varies returns a value that depends on the window."""
    t = _as_1d("time", time) - float(t0)
    s = _as_1d("sigma", sigma)
    if t.shape != s.shape or t.size < 3:
        raise ConfigError(f"need time and sigma of equal length >= 3, got {t.size} and {s.size}")
    if not (np.all(t > 0) and np.all(np.diff(t) > 0)):
        raise ConfigError("time - t0 must be positive and strictly increasing")
    if np.any(s == 0):
        raise ConfigError("sigma crosses zero inside the samples: the local exponent is defined on one side only")
    return -np.gradient(np.log(np.abs(s)), np.log(t))
