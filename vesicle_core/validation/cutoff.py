r"""How the exponent of l_* ~ S^b (Fig. 4) depends on where the PA's mode expansion is cut off.

This project's PA (eqs. 11-12, :mod:`vesicle_core.analysis.theory`) gives b = 0.430 over the workflow's S at
Delta = 0.116, the paper's PA 0.372. One candidate cause is a truncation: eqs. (11)-(12) only couple the modes
through the global tension, but a cutoff l_max removes the modes that would grow beyond it, caps l_* (eq. 31)
at the strong flows and so flattens the power law. :func:`exponent_vs_lmax` measures this directly: for each
cutoff it solves the PA at every S with :func:`theory.solve` (so with the defaults of :func:`theory.sweep` and
:func:`theory.run_theory`: seed 0, ``normalisation="area"`` (sum |u_lm|^2 = 2), the literal thermal spectrum of
Sec. V.A, fixed moduli), takes l_* = eq. (31) at t_* = argmin Delta_2 over 3 <= l <= l_max_nontrivial (the rule
of ``sweep`` and of the workflow's PA datasets) and fits l_* = c S^b with :func:`fits.fit_power_law`.

A cutoff is *active* at (l_max, S) when the modes reach it: l_max_nontrivial (largest l with some
|u_lm(t_*)| > 1e-5, Sec. V.A) equals l_max -- the condition under which :func:`theory.solve` warns. That warning
is the point of the exercise here, so it is silenced and recorded as ``truncated`` instead. When the cutoff is
inactive the result is the untruncated one except for the modes above l_max: they hold < 1e-10 of sum |u|^2 at
t_* and ~1e-5 at t = 0, where their large Gamma_l still weighs slightly in Gamma_bar of eq. (12) (measured at
Delta = 0.116, S in [227, 2224], l_max = l_max_nontrivial + 1: l_* and t_* move by < 5e-5 and < 1.4e-4 relative
against theory.default_l_max). l_* is a weighted rms of l over 3..l_max_nontrivial (eq. 31, non-negative
weights), so 3 <= l_* <= l_max_nontrivial <= l_max always: an active cutoff caps l_* at the strong flows.

Public API: :func:`exponent_vs_lmax`.
"""

from __future__ import annotations

import inspect
import warnings

import numpy as np

from ..analysis.fits import fit_power_law
from ..analysis.theory import solve
from ..errors import ConfigError, check_range

__all__ = ["exponent_vs_lmax"]

#: coordinate value standing for "no explicit cutoff": theory.default_l_max(S), which differs per S
DEFAULT_LMAX_LABEL = 0
# theory.solve's own bounds on l_max (theory._check_lmax)
_LMAX_RANGE = (3, 2000)
# arguments exponent_vs_lmax sets itself
_RESERVED = ("delta", "S", "l_max")


def _check_S(S_values):
    try:
        S = np.asarray(S_values, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"S_values must be a 1-D sequence of numbers in (0, inf), got {S_values!r}") from None
    if S.ndim != 1:
        raise ConfigError(f"S_values must be a 1-D sequence of numbers in (0, inf), got shape {S.shape}")
    # the fit's Student-t interval has n - 2 degrees of freedom
    if S.size < 3:
        raise ConfigError(f"S_values needs at least 3 values for a power-law fit with an interval, got {S.size}")
    for i, s in enumerate(S):
        check_range(f"S_values[{i}]", s, 0.0, None, lo_open=True)
        if not np.isfinite(s):
            raise ConfigError(f"S_values[{i}] must be a finite number in (0, inf), got {s!r}")
    if np.unique(S).size != S.size:
        raise ConfigError(f"S_values must be distinct, got {S.tolist()}")
    return S


def _check_lmax_values(l_max_values):
    if isinstance(l_max_values, (str, bytes)) or not np.iterable(l_max_values):
        raise ConfigError(f"l_max_values must be a sequence of integers in [{_LMAX_RANGE[0]}, {_LMAX_RANGE[1]}] "
                          f"or None (= theory.default_l_max(S)), got {l_max_values!r}")
    out = []
    for i, L in enumerate(l_max_values):
        out.append(None if L is None else check_range(f"l_max_values[{i}]", L, *_LMAX_RANGE, integer=True))
    if not out:
        raise ConfigError("l_max_values must hold at least one cutoff")
    labels = [DEFAULT_LMAX_LABEL if L is None else L for L in out]
    if len(set(labels)) != len(labels):
        raise ConfigError(f"l_max_values must be distinct, got {list(l_max_values)!r}")
    return out


def _check_solve_kwargs(solve_kwargs):
    allowed = set(inspect.signature(solve).parameters) - set(_RESERVED)
    for key in solve_kwargs:
        if key in _RESERVED:
            raise ConfigError(f"{key} is set by exponent_vs_lmax itself (use delta, S_values, l_max_values)")
        if key not in allowed:
            raise ConfigError(f"unknown solve argument {key!r}; allowed: {', '.join(sorted(allowed))}")


def _solve_grid(delta, S, cutoffs, solve_kwargs):
    """The PA (:func:`theory.solve`) at every (cutoff, S): l_* (eq. 31), l_peak, t_* and l_max_nontrivial at t_*,
    and the l_max actually solved with. -> dict of (len(cutoffs), len(S)) arrays."""
    shape = (len(cutoffs), S.size)
    out = {"l_star": np.full(shape, np.nan), "l_peak": np.full(shape, np.nan), "t_star": np.full(shape, np.nan),
           "l_max_nontrivial": np.zeros(shape, dtype=int), "l_max_used": np.zeros(shape, dtype=int)}
    for i, L in enumerate(cutoffs):
        for j, s in enumerate(S):
            with warnings.catch_warnings():
                # truncation is what is being measured; it is recorded in `truncated` instead
                warnings.filterwarnings("ignore", message="modes up to the truncation", category=UserWarning)
                sol = solve(delta, s, l_max=L, **solve_kwargs)
            out["l_star"][i, j], out["l_peak"][i, j], out["t_star"][i, j] = sol.l_star, sol.l_peak, sol.t_star
            out["l_max_nontrivial"][i, j], out["l_max_used"][i, j] = sol.l_max_nontrivial, sol.l_max
    return out


def _grid_vars(grid):
    """The (l_max, S) variables of the result, with the active-cutoff flag and its count per cutoff."""
    one = {"units": "1"}
    ls = ("l_max", "S")
    truncated = grid["l_max_nontrivial"] >= grid["l_max_used"]
    return {
        "l_star": (ls, grid["l_star"], {**one, "long_name": "eq. (31) at t_* over 3 <= l <= l_max_nontrivial"}),
        "l_peak": (ls, grid["l_peak"], {**one, "long_name": "argmax_{3<=l<=l_max_nontrivial} Delta_l(t_*)"}),
        "t_star": (ls, grid["t_star"], {"units": "1", "long_name": "t_* = argmin Delta_2, gamma_dot (t - t0)"}),
        "l_max_nontrivial": (ls, grid["l_max_nontrivial"], {**one, "long_name":
                                                             "largest l with |u_lm(t_*)| > 1e-5"}),
        "l_max_used": (ls, grid["l_max_used"], {**one, "long_name": "mode cutoff of the solve"}),
        "truncated": (ls, truncated, {"long_name": "cutoff active: l_max_nontrivial >= l_max_used"}),
        "n_truncated": ("l_max", truncated.sum(axis=1), {**one, "long_name": "number of S with an active cutoff"}),
    }


def _fit_vars(S, grid, confidence):
    """The fits l_* = c S^b and l_peak = c S^b per cutoff (:func:`fits.fit_power_law`) as (l_max,) variables."""
    fits = {name: [fit_power_law(S, row, confidence=confidence) for row in grid[name]]
            for name in ("l_star", "l_peak")}
    level = f"{confidence:.0%}"

    def per_lmax(name, key, text):
        return ("l_max", np.array([getattr(f, key) for f in fits[name]], dtype=float), {"units": "1",
                                                                                        "long_name": text})

    return {
        "b": per_lmax("l_star", "exponent", "exponent b of l_star = c S^b"),
        "b_low": per_lmax("l_star", "ci_low", f"lower end of the {level} interval of b"),
        "b_high": per_lmax("l_star", "ci_high", f"upper end of the {level} interval of b"),
        "b_stderr": per_lmax("l_star", "stderr", "standard error of b"),
        "prefactor": per_lmax("l_star", "prefactor", "c of l_star = c S^b"),
        "r2": per_lmax("l_star", "r2", "coefficient of determination in log-log"),
        "l_peak_b": per_lmax("l_peak", "exponent", "exponent of l_peak = c S^b"),
        "l_peak_b_low": per_lmax("l_peak", "ci_low", f"lower end of the {level} interval of l_peak_b"),
        "l_peak_b_high": per_lmax("l_peak", "ci_high", f"upper end of the {level} interval of l_peak_b"),
    }


def exponent_vs_lmax(delta, S_values, l_max_values, *, confidence=0.95, **solve_kwargs):
    """Exponent b of l_* ~ S^b (eq. 31, Fig. 4) for each PA mode cutoff l_max.

    delta: excess area (> 0). S_values: >= 3 distinct flow strengths (> 0). l_max_values: cutoffs, integers in
    [3, 2000], or None for :func:`theory.default_l_max` (S-dependent, the project's untruncated reference;
    labelled ``l_max = 0`` in the result). confidence: level of the fit's interval, in (0, 1). solve_kwargs:
    passed to :func:`theory.solve` (seed, kT_over_kappa, amplitudes, thermal, normalisation, t_end, rtol, atol,
    threshold); left out, the defaults of :func:`theory.sweep` apply.

    Returns an xarray Dataset with coords ``l_max`` (cutoff; 0 = default) and ``S``:

    * (l_max, S): ``l_star`` (eq. 31 at t_*), ``l_peak`` (argmax_l Delta_l(t_*), Sec. V.A), ``t_star``
      (gamma_dot (t - t0)), ``l_max_nontrivial``, ``l_max_used`` (the cutoff actually solved with) and
      ``truncated`` (bool: l_max_nontrivial reached the cutoff, i.e. modes at the cutoff are nontrivial at t_*)
    * (l_max,): ``b``, ``b_low``, ``b_high`` (interval at ``confidence``), ``b_stderr``, ``prefactor`` (c of
      l_* = c S^b), ``r2``, ``n_truncated`` (how many S are truncated) and the same fit for l_peak
      (``l_peak_b``, ``l_peak_b_low``, ``l_peak_b_high``)

    Raises ConfigError naming the offending argument for out-of-range input.
    """
    import xarray as xr

    check_range("delta", delta, 0.0, None, lo_open=True)
    check_range("confidence", confidence, 0.0, 1.0, lo_open=True, hi_open=True)
    S = _check_S(S_values)
    cutoffs = _check_lmax_values(l_max_values)
    _check_solve_kwargs(solve_kwargs)
    grid = _solve_grid(delta, S, cutoffs, solve_kwargs)
    labels = np.array([DEFAULT_LMAX_LABEL if L is None else L for L in cutoffs], dtype=int)
    coords = {
        "l_max": ("l_max", labels, {"units": "1", "long_name": f"mode cutoff of the PA ({DEFAULT_LMAX_LABEL} = "
                                                                "theory.default_l_max(S))"}),
        "S": ("S", S, {"units": "1", "long_name": "flow strength S"}),
    }
    attrs = {
        "delta": float(delta),
        "confidence": float(confidence),
        "solve_kwargs": repr(dict(sorted(solve_kwargs.items()))),
        "l_star_rule": "eq. (31) at t_* = argmin Delta_2 over 3 <= l <= l_max_nontrivial with sum_m |u_lm|^2",
        "fit": "ordinary least squares of ln l_star on ln S, Student-t interval with n-2 dof (fits.fit_power_law)",
        "source": "vesicle_core.validation.cutoff.exponent_vs_lmax",
    }
    return xr.Dataset({**_grid_vars(grid), **_fit_vars(S, grid, confidence)}, coords=coords, attrs=attrs)
