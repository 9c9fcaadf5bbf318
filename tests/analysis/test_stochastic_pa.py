"""Stochastic PA (stochastic_pa.py): the noiseless limit against theory.solve, the exact area constraint, the
equilibrium spectrum against equipartition (and that a wrong noise fails it), step convergence, bad input."""

import numpy as np
import pytest

from vesicle_core.analysis import stochastic_pa as SP
from vesicle_core.analysis import theory as T
from vesicle_core.errors import ConfigError
from vesicle_core.model import modes as Mo


def test_mode_table_counts_every_m_once_with_its_mirror():
    t = SP.ModeTable.build(6)
    full = np.zeros((7, 13), complex)
    rng = np.random.default_rng(1)
    for l in range(2, 7):
        for m in range(0, l + 1):
            z = rng.standard_normal(2) @ [1, 1j] if m else rng.standard_normal()
            full[l, 6 + m] = z
            full[l, 6 - m] = (-1) ** m * np.conj(z)
    assert np.allclose(t.delta_l(t.from_full(full)), np.sum(np.abs(full) ** 2, axis=-1))
    assert (t.l[t.forced], t.m[t.forced]) == (2, 2)


def test_without_noise_it_is_the_deterministic_pa():
    """Same start (theory's literal thermal state), no noise, no pre-phase: t_*, l_* and l_peak of theory.solve,
    to the step's resolution (t_end / n_steps = 3.6e-4 in t) and O(ds) in l_*."""
    S, L = 553.0, 40
    ref = T.solve(0.116, S, l_max=L)
    u0 = Mo.initial_state(L, S, delta=0.116)
    run = SP.simulate(0.116, S, noise="off", u0=u0, pre_phase=0, l_max=L, n_steps=4000)
    step = run.t[1] - run.t[0]
    assert abs(run.t_star[0] - ref.t_star) <= step
    assert run.l_star[0] == pytest.approx(ref.l_star, abs=5e-3)
    assert run.l_peak[0] == ref.l_peak
    assert run.sum_u2_error < 1e-11


def test_mean_field_state_without_noise_is_the_stretched_state():
    S = 553.0
    sig, u22 = SP.mean_field_tension(0.116, S, 20, 0.0)
    assert sig == pytest.approx((S - float(Mo.gamma_l(2))) / float(Mo.a_l(2)), rel=1e-12)
    assert u22 == pytest.approx(1.0, rel=1e-12)
    # noise takes area from u_22 and raises the tension, never exceeds the excess area
    sig_hot, u22_hot = SP.mean_field_tension(0.116, S, 40, 0.405)
    assert sig_hot > sig and 0 < u22_hot < 1


def test_noisy_run_keeps_the_area_exactly_and_seeds_differ():
    run = SP.simulate(0.116, 553.0, seeds=(3, 4), l_max=20, n_steps=400)
    assert run.sum_u2_error < 1e-11
    assert run.Delta_2.shape == (2, 400)
    assert not np.allclose(run.Delta_2[0], run.Delta_2[1])
    # one generator per seed: the same seeds give the same numbers bit for bit; a seed in another ensemble gives
    # its path to the tension solve's tolerance (the vectorised iteration count depends on the other seeds)
    assert np.array_equal(SP.simulate(0.116, 553.0, seeds=(3, 4), l_max=20, n_steps=400).Delta_2, run.Delta_2)
    alone = SP.simulate(0.116, 553.0, seeds=(3,), l_max=20, n_steps=400)
    assert np.allclose(alone.Delta_2[0], run.Delta_2[0], rtol=1e-8, atol=0)


def _equilibrium_ratio(n_steps=5000):
    # 32 seeds x 2 (in tau) = 32 x 40 relaxation times of the slowest mode, 1/lam_2 = 0.05 at <sigma> ~ 41
    eq = SP.equilibrium(0.04, l_max=16, seeds=range(32), ds=4e-4, n_steps=n_steps, burn_in=250)
    theory = SP.equilibrium_variance(eq["l"][2:], eq["sigma_mean"], 0.04)
    return eq, eq["var"][2:] / theory, eq["var_se"][2:] / theory


def test_equilibrium_spectrum_is_equipartition_at_the_mean_tension():
    """S = 0, kT/kappa = 0.0405, Delta = 0.04: <|u_lm|^2> = kT / (kappa Delta [l(l+1) + <sigma>]) for every l
    within 10% (the issue's bound; the sampling error is ~1.3% at l = 2) and <sigma> within 5% of the mean-field
    tension. (l = 2-3 sit 2-5% low, more than the exact fixed-area ensemble's 2%: docs/history/thermal.md, section
    6.)"""
    eq, ratio, se = _equilibrium_ratio()
    assert np.all(np.abs(ratio - 1) < 0.10), ratio
    assert np.all(se < 0.03), se
    assert eq["sigma_mean"] == pytest.approx(eq["sigma_mean_field"], rel=0.05)


def test_equilibrium_check_rejects_a_wrong_noise(monkeypatch):
    """The same check with the noise amplitude off by sqrt 2 (diffusivity x 2) fails: the check can fail."""
    build = SP._Rates.build

    def doubled(*a, **k):
        r = build(*a, **k)
        return SP._Rates(r.G, r.A, 2 * r.D)

    monkeypatch.setattr(SP._Rates, "build", doubled)
    _, ratio, _ = _equilibrium_ratio(n_steps=2000)
    assert np.mean(np.abs(ratio - 1) > 0.10) > 0.9


def test_thermal_start_converges_with_the_step():
    """Equilibrium start, deterministic afterwards (noise='start', no pre-phase): the same draws at n and 2n steps
    give l_* that converges at first order in the step (the tension is held over a step): the difference halves
    and the finer pair agrees within 0.02."""
    out = [SP.simulate(0.116, 553.0, seeds=(0, 1), l_max=30, noise="start", pre_phase=0, n_steps=n)
           for n in (500, 1000, 2000)]
    dl = [np.max(np.abs(out[i + 1].l_star - out[i].l_star)) for i in range(2)]
    assert dl[1] < 0.6 * dl[0] and dl[1] < 0.02


@pytest.mark.parametrize(
    "kw, field",
    [({"kT_over_kappa": -0.1}, "kT_over_kappa"), ({"seeds": (1.5,)}, "noise_seed"), ({"seeds": ("3",)}, "noise_seed"),
     ({"noise": "always"}, "noise"), ({"n_steps": 3}, "n_steps"), ({"pre_phase": -1.0}, "pre_phase")],
)
def test_bad_input_names_the_field(kw, field):
    with pytest.raises(ConfigError, match=field):
        SP.simulate(0.116, 553.0, l_max=10, **kw)


def test_bad_case_names_the_field():
    with pytest.raises(ConfigError, match="S"):
        SP.simulate(0.116, 0.0)
    with pytest.raises(ConfigError, match="delta"):
        SP.simulate(-0.1, 553.0)
