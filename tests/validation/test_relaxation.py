"""Single-mode relaxation of a sphere against linear Stokes theory (the IBM resolution test)."""

import numpy as np
import pytest

from vesicle_core.model.modes import a_l, gamma_l
from vesicle_core.validation.relaxation import clean_mobility, l_res, mode_rate, theory_rate


def test_clean_theory_is_taylors_drop_rate_at_l2():
    lam = 1.0  # equal viscosities
    taylor = 40 * (lam + 1) / ((2 * lam + 3) * (19 * lam + 16))  # rate of l = 2 in gamma / (mu R)
    assert clean_mobility(2) * (2 - 1) * (2 + 2) == pytest.approx(taylor, rel=1e-12)


def test_inextensible_rates_are_slower_than_clean_ones():
    # the area constraint removes freedom: every mode relaxes more slowly, and both agree at large l
    l = np.arange(2, 200)
    inext, clean = theory_rate(l, "inextensible"), theory_rate(l, "clean")
    assert np.all(inext < clean)
    assert inext[-1] / clean[-1] == pytest.approx(1.0, abs=0.01)
    np.testing.assert_allclose(theory_rate(l, "inextensible", 300.0), gamma_l(l) + 300.0 * a_l(l))


def test_l2_rate_matches_theory_after_the_box_correction():
    # N = 64, edge ~ 2h. The periodic box slows l = 2 by r(L) = r_inf - c / L^3: measure at L = 5 and 7 R (same h)
    r5 = mode_rate(2, 64, 642, L=5.0).ratio
    r7 = mode_rate(2, 90, 642, L=90 * 5.0 / 64).ratio
    L7 = 90 * 5.0 / 64
    c = (r7 - r5) / (1 / 5.0**3 - 1 / L7**3)
    r_inf = r7 + c / L7**3
    assert r5 < r7 < r_inf  # a larger box is faster
    assert abs(r_inf - 1.0) < 0.03


def test_rates_converge_with_the_grid():
    # the kernel smears the membrane over ~h: the error at fixed l shrinks as h does
    err = {N: abs(mode_rate(4, N, 642).ratio - 1.0) for N in (32, 64)}
    assert err[64] < 0.6 * err[32]


@pytest.mark.slow
def test_inextensible_l2_rate_is_gamma_2():
    r = mode_rate(2, 64, 642, membrane="inextensible")
    assert r.theory == pytest.approx(gamma_l(2))
    assert 0.85 < r.ratio < 1.0  # the periodic box slows l = 2 by ~5% at L = 5 R (see above)


def test_l_res_is_the_first_failure():
    assert l_res({2: 1.01, 3: 0.97, 4: 0.94, 6: 0.99}) == 3
    assert l_res({2: 0.9}) == 0
