r"""Linear mode physics of a quasi-spherical vesicle (Sec. III, eqs. 10-12): the rates Gamma_l and A_l, the thermal
initial spectrum and the stationary stretched state the perturbation analysis starts from.

The solver uses these for its step estimate (the fastest resolved mode) and its thermal seed, the analysis for the
PA (:mod:`vesicle_core.analysis.theory`, whose docstring explains the normalisation sum |u_lm|^2 = 2 and the
"literal" reading of the thermal spectrum); the validation compares IBM rates with them. They are model, below all
three.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError, check_choice, check_range
from .units import Params

#: total sum |u_lm|^2 of each normalisation
NORMALISATIONS = {"area": 2.0, "unit": 1.0}
AMPLITUDES = ("fixed", "gaussian")
THERMAL = ("literal", "physical")


def gamma_l(l):
    """Gamma_l = (l-1) l^2 (l+1)^2 (l+2) / (4l^3 + 6l^2 - 1) of eq. (11)."""
    l = np.asarray(l, dtype=float)
    return (l - 1) * l**2 * (l + 1) ** 2 * (l + 2) / (4 * l**3 + 6 * l**2 - 1)


def a_l(l):
    """A_l = l (l+1) (l^2 + l - 2) / (4l^3 + 6l^2 - 1) of eq. (11)."""
    l = np.asarray(l, dtype=float)
    return l * (l + 1) * (l**2 + l - 2) / (4 * l**3 + 6 * l**2 - 1)


def _kT(kT_over_kappa):
    if kT_over_kappa is None:
        return Params().kT_over_kappa
    check_range("kT_over_kappa", kT_over_kappa, 0.0, None)
    return float(kT_over_kappa)


def thermal_variance(l, S, kT_over_kappa=None, *, delta=None, thermal="literal"):
    """Mean |u_lm|^2 of the initial thermal spectrum, 2 k_B T / (kappa (l^4 + S l^2 / A_2)) (Sec. V.A).

    ``thermal="literal"`` puts it on the scaled u_lm (default, see module docstring); ``"physical"`` multiplies
    by (l-1)(l+2)/delta (the formula read as the spectrum of the unscaled amplitude). Zero for l < 2.
    """
    check_choice("thermal", thermal, THERMAL)
    l = np.asarray(l, dtype=float)
    kt = _kT(kT_over_kappa)
    check_range("S", S, 0.0, None)
    A2 = float(a_l(2))
    with np.errstate(divide="ignore", invalid="ignore"):
        var = np.where(l >= 2, 2.0 * kt / (l**4 + S * l**2 / A2), 0.0)
    if thermal == "physical":
        if delta is None:
            raise ConfigError("thermal='physical' needs delta")
        check_range("delta", delta, 0.0, None, lo_open=True)
        var = var * np.where(l >= 2, (l - 1) * (l + 2), 0.0) / float(delta)
    return var


def _check_lmax(l_max):
    return check_range("l_max", l_max, 3, 2000, integer=True)


def initial_state(l_max, S, *, delta=None, seed=0, kT_over_kappa=None, amplitudes="fixed", thermal="literal",
                  normalisation="area"):
    """Stationary stretched state of the forward flow plus the thermal spectrum, as a complex array.

    Shape (l_max+1, 2 l_max+1), ``u[l, l_max + m]`` = u_lm (the layout of ``harmonics.py``); zero for |m| > l
    and for l < 2. u_{2,+-2} is real and positive, fixed by sum |u|^2 = N of the normalisation.
    """
    L = _check_lmax(l_max)
    check_choice("amplitudes", amplitudes, AMPLITUDES)
    check_choice("normalisation", normalisation, tuple(NORMALISATIONS))
    check_range("seed", seed, 0, None, integer=True)
    N = NORMALISATIONS[normalisation]
    var = thermal_variance(np.arange(L + 1), S, kT_over_kappa, delta=delta, thermal=thermal)
    rng = np.random.default_rng(int(seed))
    u = np.zeros((L + 1, 2 * L + 1), dtype=complex)
    for l in range(2, L + 1):
        sd = math.sqrt(var[l])
        m = np.arange(1, l + 1)
        if amplitudes == "fixed":
            phase = rng.uniform(0.0, 2.0 * np.pi, size=l)
            pos = sd * np.exp(1j * phase)
            zero = sd * (1.0 if rng.random() < 0.5 else -1.0)
        else:
            z = rng.standard_normal((2, l))
            pos = sd * (z[0] + 1j * z[1]) / math.sqrt(2.0)
            zero = sd * float(rng.standard_normal())
        u[l, L + m] = pos
        u[l, L - m] = (-1.0) ** m * np.conj(pos)
        u[l, L] = zero
    u[2, L + 2] = u[2, L - 2] = 0.0
    rest = float(np.sum(np.abs(u) ** 2))
    if rest >= N:
        raise ConfigError(
            f"the thermal modes hold sum |u|^2 = {rest:.3g} >= {N:g}, the whole excess area "
            f"(thermal={thermal!r}, l_max={L}); use thermal='literal' or a smaller l_max"
        )
    u[2, L + 2] = u[2, L - 2] = math.sqrt((N - rest) / 2.0)
    return u


def _sigma0_magnitude(S, normalisation):
    v0 = math.sqrt(NORMALISATIONS[normalisation] / 2.0)
    return (S / v0 + float(gamma_l(2))) / float(a_l(2))


def default_l_max(S, normalisation="area"):
    """Default truncation: max(40, ceil(0.75 sqrt|sigma_0|) + 8), sigma_0 = -(S/u_22 + Gamma_2)/A_2 the stage-1
    tension. Modes with l(l+1) > |sigma_0| never grow; the nontrivial modes at t_* (|u_lm| > 1e-5) stay below
    ~0.75 sqrt|sigma_0| over S in [100, 9500] (e.g. l_max_nontrivial = 27, 47, 80 at S = 553, 2224, 9500 for
    Delta = 0.116), and l_star changes by < 1e-5 (relative) when l_max is raised further."""
    return int(max(40, math.ceil(0.75 * math.sqrt(_sigma0_magnitude(S, normalisation))) + 8))
