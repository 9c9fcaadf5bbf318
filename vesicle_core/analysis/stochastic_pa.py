r"""Stochastic perturbation analysis: the mode equations (11)-(12) with their thermal forcing.

Model
-----
The deterministic PA (:mod:`vesicle_core.analysis.theory`) relaxes each scaled amplitude u_lm (eq. 10) at the rate
lam_l = Gamma_l + A_l sigma = A_l [l(l+1) + sigma] (Gamma_l / A_l = l(l+1)). Helfrich's energy at tension sigma is
(kappa/2) sum_lm (l-1)(l+2)[l(l+1) + sigma] |c_lm|^2 with c_lm = sqrt(Delta/((l-1)(l+2))) u_lm, so for u it is
(kappa Delta / 2) sum_lm [l(l+1) + sigma] |u_lm|^2 and eq. (11) is du/ds = -(A_l / (kappa Delta)) dE/du* + forcing:
the mode mobility is A_l / (kappa Delta). Fluctuation-dissipation then fixes the noise::

    du_lm = [S(t) f_lm - lam_l u_lm] ds + sqrt(2 D_l) dW_lm,     D_l = A_l kT / (kappa Delta)

(s = t/tau; dW complex with E|dW|^2 = ds for m > 0, real for m = 0; u_{l,-m} = (-1)^m conj(u_lm)), whose
stationary spectrum at fixed sigma is the equilibrium one, ``<|u_lm|^2> = kT / (kappa Delta [l(l+1) + sigma])``
(:func:`equilibrium_variance`; docs/explanation/thermal-noise.md, section 4, derives it and relates it to the
paper's initial
spectrum). On a grid, ``grid_h``/``kernel``/``coupling`` multiply lam_l and D_l by the same r_l
(:func:`theory.grid_damping`): the mobility is damped, the equilibrium spectrum is not.

The tension is the Lagrange multiplier of the area constraint sum |u_lm|^2 = 2 (the normalisation of theory.py).
Deterministically eq. (12) is d/ds sum |u|^2 = 0; with noise the constraint must also absorb the noise's Ito
term sum 2 D_l, so rather than eq. (12) each step solves for the sigma that puts the step's end exactly on the
constraint (held constant over the step; a secant iteration from the last tension, bracketed Illinois
regula falsi as the safeguard; |sum |u|^2 - 2| < 1e-12).

Step (exact for an Ornstein-Uhlenbeck process at fixed sigma, so the stiff high modes need no small step)::

    u' = e^{-lam ds} u + S f ds phi(lam ds) + sqrt(2 D ds phi(2 lam ds)) xi,    phi(x) = (1 - e^{-x}) / x

with xi standard complex (real for m = 0) normal, drawn from ``numpy.random.default_rng(seed)`` per seed.

A run (:func:`simulate`): the forward flow's stationary state with its equilibrium spectrum (the mean-field
state of :func:`stationary_state`, Gaussian draws), a pre-phase of ``pre_phase`` tau/S under +S to equilibrate
it with noise on, then the reversal (S -> -S) to ``t_end`` (theory.default_t_end). t_* = argmin Delta_2 after
the reversal, per seed; l_* (eq. 31) and l_peak from Delta_l(t_*) over 3 <= l <= l_max (the truncation: with
noise every mode is nontrivial, so l_max is a physical input -- the grid's resolved l for comparison with the
IBM). ``noise="start"`` switches the noise off at the reversal: the deterministic PA from an equilibrium start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.special import exprel

from ..errors import ConfigError, check_choice, check_counter, check_range
from ..model.modes import _check_lmax, _kT, a_l, default_l_max, gamma_l
from ..model.units import chi_from_S
from .harmonics import characteristic_l

__all__ = ["ModeTable", "equilibrium_variance", "mean_field_tension", "stationary_state", "simulate", "equilibrium",
           "StochasticPA", "NOISE"]

NOISE = ("on", "start", "off")
_TOL = 1e-12


@dataclass(frozen=True)
class ModeTable:
    """Flat list of the independent modes l = 2..l_max, m = 0..l (u_{l,-m} follows from u_lm).

    ``w`` counts each mode's copies in sum_m |u_lm|^2 (1 for m = 0, 2 for m > 0); ``forced`` is the index of
    u_22, the mode the flow drives (eq. 11: f_lm = delta_l2 (delta_m2 + delta_m-2))."""

    l_max: int
    l: np.ndarray = field(repr=False)
    m: np.ndarray = field(repr=False)
    w: np.ndarray = field(repr=False)
    forced: int = 2

    @classmethod
    def build(cls, l_max):
        L = _check_lmax(l_max)
        l = np.concatenate([np.full(k + 1, k) for k in range(2, L + 1)])
        m = np.concatenate([np.arange(k + 1) for k in range(2, L + 1)])
        return cls(L, l, m, np.where(m == 0, 1.0, 2.0), forced=2)

    def delta_l(self, u):
        """Delta_l = sum_m |u_lm|^2 for l = 0..l_max (zero for l < 2), shape (..., l_max + 1)."""
        p = self.w * np.abs(u) ** 2
        out = np.zeros(p.shape[:-1] + (self.l_max + 1,))
        # the modes are sorted by l, so one reduceat sums each l's run (l = k starts at k (k+1)/2 - 3)
        starts = np.array([k * (k + 1) // 2 - 3 for k in range(2, self.l_max + 1)])
        out[..., 2:] = np.add.reduceat(p, starts, axis=-1)
        return out

    def from_full(self, u):
        """The flat modes of a full (l_max+1, 2 l_max+1) array in the layout of ``harmonics.py``."""
        u = np.asarray(u)
        return u[..., self.l, self.l_max + self.m]


def equilibrium_variance(l, sigma, delta, kT_over_kappa=None):
    """<|u_lm|^2> = kT / (kappa Delta [l(l+1) + sigma]) at fixed tension sigma (kappa/R^2), every m; eq. (10)'s
    scaled amplitudes. Needs l(l+1) + sigma > 0 (a stable mode)."""
    l = np.asarray(l, dtype=float)
    check_range("delta", delta, 0.0, None, lo_open=True)
    stiff = l * (l + 1) + float(sigma)
    if np.any(stiff <= 0):
        raise ConfigError(f"sigma = {sigma:g} makes modes l <= {l.max():g} unstable (l(l+1) + sigma <= 0)")
    return _kT(kT_over_kappa) / (float(delta) * stiff)


def mean_field_tension(delta, S, l_max, kT_over_kappa=None):
    """Tension and u_22 of the stationary state under the forward flow S >= 0 with the equilibrium spectrum (mean
    field): 2 u_22^2 + sum_{modes != u_22} w <|u_lm|^2>(sigma) = 2, u_22 = S / lam_2(sigma) (S = 0: u_22 thermal).

    The left side falls from +inf at sigma = -6 (lam_2 = A_2 (6 + sigma) = 0) to 0, so there is one root: a
    large kT raises the tension above the deterministic (S - Gamma_2)/A_2 instead of exceeding the area."""
    t = ModeTable.build(l_max)
    kt = _kT(kT_over_kappa)
    check_range("S", S, 0.0, None)
    if S == 0 and kt == 0:
        raise ConfigError("S = 0 and kT = 0 have no stationary state; give S > 0 or kT > 0")
    a2 = float(a_l(2))
    lf = t.l.astype(float)
    thermal_w = np.where(np.arange(lf.size) == t.forced, 1.0 if S == 0 else 0.0, 1.0) * t.w

    def excess(sig):
        u22 = S / (a2 * (6.0 + sig))
        return 2.0 * u22**2 + float(np.sum(thermal_w * kt / (delta * (lf * (lf + 1) + sig)))) - 2.0

    lo, hi = -6.0 + 1e-12, 10.0
    while excess(hi) > 0:
        hi = 4.0 * hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if excess(mid) > 0 else (lo, mid)
        if hi - lo <= 1e-14 * abs(mid):
            break
    sig = 0.5 * (lo + hi)
    return sig, S / (a2 * (6.0 + sig))


def _draw(rng, n_modes, m):
    """Standard normal deviates, complex with E|xi|^2 = 1 for m > 0 and real for m = 0."""
    z = rng.standard_normal((2, n_modes))
    return np.where(m == 0, z[0], (z[0] + 1j * z[1]) / math.sqrt(2.0))


def stationary_state(table, delta, S, kT_over_kappa, rngs):
    """One draw per generator of the forward flow's stationary state: u_22 real at its mean-field value, the other
    modes Gaussian at the equilibrium spectrum of the mean-field tension, rescaled so that sum |u|^2 = 2 exactly.
    Returns (u (n, modes), mean-field sigma)."""
    sig, u22 = mean_field_tension(delta, S, table.l_max, kT_over_kappa)
    var = equilibrium_variance(table.l, sig, delta, kT_over_kappa) if _kT(kT_over_kappa) > 0 else 0 * table.w
    forced = S > 0
    if forced:
        var[table.forced] = 0.0
    u = np.stack([_draw(r, table.l.size, table.m) for r in rngs]) * np.sqrt(var)
    if forced:
        u[:, table.forced] = u22
    free = (table.w * np.abs(u) ** 2).sum(axis=-1) - (2.0 * u22**2 if forced else 0.0)
    room = 2.0 - (2.0 * u22**2 if forced else 0.0)
    scale = np.sqrt(room / np.where(free > 0, free, 1.0))
    keep = np.arange(table.l.size) == table.forced if forced else np.zeros(table.l.size, bool)
    u = np.where(keep, u, u * scale[:, None])
    return u, sig


@dataclass
class _Rates:
    """Per-l rates on the (possibly damped) grid: lam_l = G_l + A_l sigma, noise D_l = A_l kT / (kappa Delta)."""

    G: np.ndarray
    A: np.ndarray
    D: np.ndarray

    @classmethod
    def build(cls, L, delta, kt, grid_h=None, kernel=None, coupling=None):
        from .theory import grid_damping

        l = np.arange(2, L + 1)
        r = grid_damping(l, grid_h, kernel, coupling)
        A = r * a_l(l)
        return cls(r * gamma_l(l), A, A * kt / delta)


def _advance(u, sig, S_t, xi, ds, rates, idx, forced):
    """u after one exact OU step at tension sig (n,) (module docstring); idx maps modes to l - 2."""
    x = (rates.G + rates.A * sig[:, None]) * ds  # (n, L-1)
    with np.errstate(over="ignore", invalid="ignore"):
        decay = np.exp(-x)[:, idx]
        noise = np.sqrt(2.0 * rates.D * ds * exprel(-2.0 * x))[:, idx]
        out = decay * u + noise * xi
        out[:, forced] += S_t * ds * exprel(-x[:, 0])
    return out


def _constrained_step(u, sig0, S_t, xi, ds, rates, table):
    """The step and the per-seed tension that puts it on sum w |u|^2 = 2 (bracket, then Illinois)."""
    idx = table.l - 2

    def F(s):
        v = _advance(u, s, S_t, xi, ds, rates, idx, table.forced)
        f = (table.w * np.abs(v) ** 2).sum(axis=-1) - 2.0
        return np.where(np.isfinite(f), f, np.inf), v

    # secant from the last tension: F is smooth and nearly linear over a step's change, so this converges in a
    # few evaluations; the bracketed Illinois iteration below is the safeguard
    d = 1e-3 * np.maximum(1.0, np.abs(sig0))
    s0, s1 = sig0, sig0 + d
    f0, f1 = F(s0)[0], F(s1)[0]
    for _ in range(12):
        with np.errstate(divide="ignore", invalid="ignore"):
            s2 = s1 - f1 * (s1 - s0) / (f1 - f0)
        if not np.all(np.isfinite(s2)):
            break
        f2, v = F(s2)
        if np.all(np.abs(f2) < _TOL):
            return v, s2
        s0, f0, s1, f1 = s1, f1, s2, f2
    lo, hi = sig0 - d, sig0 + d
    flo, fhi = F(lo)[0], F(hi)[0]
    for _ in range(80):
        bad_lo, bad_hi = flo <= 0, fhi >= 0
        if not (bad_lo.any() or bad_hi.any()):
            break
        d = 4.0 * d
        lo = np.where(bad_lo, lo - d, lo)
        hi = np.where(bad_hi, hi + d, hi)
        flo, fhi = np.where(bad_lo, F(lo)[0], flo), np.where(bad_hi, F(hi)[0], fhi)
    else:
        raise ConfigError("stochastic PA: no tension brackets the area constraint; reduce the step (n_steps)")
    side = np.zeros_like(sig0)
    for _ in range(200):
        flo_c, fhi_c = np.minimum(flo, 1e300), np.maximum(fhi, -1e300)
        s = (lo * fhi_c - hi * flo_c) / (fhi_c - flo_c)
        s = np.where(np.isfinite(s) & (s > lo) & (s < hi), s, 0.5 * (lo + hi))
        fs, v = F(s)
        if np.all(np.abs(fs) < _TOL):
            return v, s
        pos = fs > 0
        lo, flo = np.where(pos, s, lo), np.where(pos, fs, flo)
        hi, fhi = np.where(pos, hi, s), np.where(pos, fhi, fs)
        # Illinois: halve the stale end's value when the same end is kept twice in a row
        fhi = np.where(pos & (side > 0), 0.5 * fhi, fhi)
        flo = np.where(~pos & (side < 0), 0.5 * flo, flo)
        side = np.where(pos, 1.0, -1.0)
    raise ConfigError("stochastic PA: the tension solve did not converge")


@dataclass
class StochasticPA:
    """One ensemble of :func:`simulate`. Times t are gamma_dot (t - t0), per seed along the first axis."""

    delta: float
    S: float
    chi: float
    kT_over_kappa: float
    l_max: int
    seeds: tuple
    noise: str
    ds: float
    sigma_start: float  # the mean-field tension the ensemble starts from
    t: np.ndarray = field(repr=False)  # (steps,) after the reversal
    Delta_2: np.ndarray = field(repr=False)  # (n, steps)
    sigma: np.ndarray = field(repr=False)  # (n, steps)
    t_star: np.ndarray = field(repr=False)  # (n,)
    Delta_l_star: np.ndarray = field(repr=False)  # (n, l_max + 1)
    sum_u2_error: float = 0.0  # max |sum |u|^2 - 2| over all steps and seeds

    @property
    def l_star(self):
        """Eq. (31) at each seed's t_* over 3 <= l <= l_max."""
        return characteristic_l(self.Delta_l_star, self.l_max, method="eq31")

    @property
    def l_peak(self):
        """argmax_l Delta_l(t_*) per seed (the definition at the start of Sec. V.A)."""
        return characteristic_l(self.Delta_l_star, self.l_max, method="peak")

    def summary(self) -> dict:
        """Mean and sample standard deviation over seeds of l_*, l_peak and t_*."""
        out = {"n_seeds": len(self.seeds)}
        for name in ("l_star", "l_peak", "t_star"):
            v = np.asarray(getattr(self, name), float)
            out[name] = float(v.mean())
            out[name + "_sd"] = float(v.std(ddof=1)) if v.size > 1 else 0.0
        return out


def _check_seeds(seeds):
    seeds = (seeds,) if np.ndim(seeds) == 0 else tuple(seeds)
    if not seeds:
        raise ConfigError("seeds must hold at least one integer")
    return tuple(check_counter("noise_seed", s) for s in seeds)


def _run_phase(u, sig, S_t, n_steps, ds, rates, table, rngs, noisy, record):
    """n_steps constrained steps at flow S_t; record(k, u, sig) after each; returns (u, sig, max constraint error)."""
    err = 0.0
    zero = np.zeros((len(rngs), table.l.size))
    for k in range(n_steps):
        xi = np.stack([_draw(r, table.l.size, table.m) for r in rngs]) if noisy else zero
        u, sig = _constrained_step(u, sig, S_t, xi, ds, rates, table)
        err = max(err, float(np.max(np.abs((table.w * np.abs(u) ** 2).sum(axis=-1) - 2.0))))
        if record is not None:
            record(k, u, sig)
    return u, sig, err


def simulate(delta, S, *, seeds=(0,), kT_over_kappa=None, l_max=None, n_steps=4000, pre_phase=5.0, t_end=None,
             noise="on", u0=None, grid_h=None, kernel=None, coupling=None) -> StochasticPA:
    """Stochastic PA of one case over an ensemble of seeds (module docstring).

    delta, S: excess area and flow strength (> 0); kT_over_kappa: k_B T / kappa (default 0.0405, Table III);
    l_max: truncation (default theory's default_l_max); n_steps: steps after the reversal (the pre-phase uses the
    same step); pre_phase: its length in tau / S (0: start at the reversal); t_end: default theory.default_t_end;
    noise: "on" throughout, "start" (equilibrium start, deterministic after the reversal) or "off";
    u0: explicit start, flat modes (n or 1, modes) or a full (l_max+1, 2 l_max+1) array (then no stationary draw).
    """
    from .theory import default_t_end

    check_range("delta", delta, 0.0, None, lo_open=True)
    check_range("S", S, 0.0, None, lo_open=True)
    check_choice("noise", noise, NOISE)
    check_range("n_steps", n_steps, 10, None, integer=True)
    check_range("pre_phase", pre_phase, 0.0, None)
    seeds = _check_seeds(seeds)
    delta, S, kt = float(delta), float(S), _kT(kT_over_kappa)
    table = ModeTable.build(default_l_max(S) if l_max is None else l_max)
    chi = chi_from_S(S, delta)
    t_end = default_t_end(delta, S) if t_end is None else check_range("t_end", t_end, 0.0, None, lo_open=True)
    ds = float(t_end) / chi / n_steps
    rates = _Rates.build(table.l_max, delta, kt if noise != "off" else 0.0, grid_h, kernel, coupling)
    rngs = [np.random.default_rng(s) for s in seeds]
    if u0 is None:
        u, sig_mf = stationary_state(table, delta, S, kt if noise != "off" else 0.0, rngs)
    else:
        u = np.asarray(u0, dtype=complex)
        u = table.from_full(u) if u.ndim == 2 and u.shape[-1] == 2 * table.l_max + 1 else u
        u = np.broadcast_to(u, (len(seeds), table.l.size)).copy()
        sig_mf = mean_field_tension(delta, S, table.l_max, 0.0)[0]
    sig = np.full(len(seeds), sig_mf)
    n_pre = int(round(pre_phase / S / ds))
    u, sig, err = _run_phase(u, sig, S, n_pre, ds, rates, table, rngs, noise != "off", None)
    rec = {"D2": np.empty((len(seeds), n_steps)), "sig": np.empty((len(seeds), n_steps)),
           "best": np.full(len(seeds), np.inf), "k": np.zeros(len(seeds), int),
           "Dl": np.zeros((len(seeds), table.l_max + 1))}

    def record(k, v, s):
        Dl = table.delta_l(v)
        rec["D2"][:, k], rec["sig"][:, k] = Dl[:, 2], s
        new = Dl[:, 2] < rec["best"]
        rec["best"] = np.where(new, Dl[:, 2], rec["best"])
        rec["k"] = np.where(new, k, rec["k"])
        rec["Dl"][new] = Dl[new]

    after = rates if noise == "on" else _Rates(rates.G, rates.A, 0.0 * rates.D)
    u, sig, err2 = _run_phase(u, sig, -S, n_steps, ds, after, table, rngs, noise == "on", record)
    t = (np.arange(n_steps) + 1) * ds * chi
    if np.any(rec["k"] == n_steps - 1):
        raise ConfigError(f"Delta_2 is still decreasing at t_end = {t_end:g} for some seed: increase t_end")
    return StochasticPA(delta=delta, S=S, chi=chi, kT_over_kappa=kt, l_max=table.l_max, seeds=seeds, noise=noise,
                        ds=ds, sigma_start=float(sig_mf), t=t, Delta_2=rec["D2"], sigma=rec["sig"],
                        t_star=t[rec["k"]], Delta_l_star=rec["Dl"], sum_u2_error=max(err, err2))


def equilibrium(delta, *, l_max, kT_over_kappa=None, seeds=(0,), ds=1e-4, n_steps=20000, burn_in=2000,
                n_batches=4, grid_h=None, kernel=None, coupling=None) -> dict:
    """The free (S = 0) vesicle with noise: time- and seed-averaged <|u_lm|^2> per l after ``burn_in`` steps.

    Returns dict with l, var (measured <|u_lm|^2>, l = 0..l_max; NaN for l < 2), var_se (its standard error from
    ``n_batches`` batch means per seed: make a batch several 1/lam_2 long), sigma_mean, sigma_sd, sigma_mean_field
    (:func:`mean_field_tension` at S = 0)."""
    check_range("ds", ds, 0.0, None, lo_open=True)
    check_range("n_steps", n_steps, 32, None, integer=True)
    check_range("burn_in", burn_in, 0, None, integer=True)
    seeds = _check_seeds(seeds)
    kt = _kT(kT_over_kappa)
    check_range("kT_over_kappa", kt, 0.0, None, lo_open=True)
    table = ModeTable.build(l_max)
    rates = _Rates.build(table.l_max, float(delta), kt, grid_h, kernel, coupling)
    rngs = [np.random.default_rng(s) for s in seeds]
    u, sig_mf = stationary_state(table, float(delta), 0.0, kt, rngs)
    sig = np.full(len(seeds), sig_mf)
    u, sig, _ = _run_phase(u, sig, 0.0, burn_in, ds, rates, table, rngs, True, None)
    count = np.array([2 * k + 1 for k in range(table.l_max + 1)], float)
    nb = check_range("n_batches", n_batches, 1, n_steps, integer=True)
    per = n_steps // nb
    acc = np.zeros((len(seeds), nb, table.l_max + 1))
    sigs = np.zeros((len(seeds), n_steps))

    def record(k, v, s):
        if k < nb * per:
            acc[:, k // per] += table.delta_l(v) / count
        sigs[:, k] = s

    _run_phase(u, sig, 0.0, n_steps, ds, rates, table, rngs, True, record)
    batches = (acc / per).reshape(-1, table.l_max + 1)
    var = batches.mean(axis=0)
    se = batches.std(axis=0, ddof=1) / math.sqrt(batches.shape[0])
    var[:2] = se[:2] = np.nan
    return {"l": np.arange(table.l_max + 1), "var": var, "var_se": se, "sigma_mean": float(sigs.mean()),
            "sigma_sd": float(sigs.std()), "sigma_mean_field": float(sig_mf)}
