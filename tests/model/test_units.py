import math

import pytest

from vesicle_core.errors import ConfigError
from vesicle_core.model.units import Params, S_from_chi, chi_from_S


@pytest.mark.parametrize(
    "R, gdot, delta, chi, S",
    [
        (1.671e-5, 1.0, 0.116, 67.0, 553.0),
        (1.671e-5, 4.0, 0.116, 268.0, 2224.0),
        (1.8e-5, 1.0, 0.997, 83.5, 237.0),
        (1.8e-5, 4.0, 0.997, 335.0, 947.0),
    ],
)
def test_paper_pairs(R, gdot, delta, chi, S):
    p = Params(R=R, gamma_dot=gdot, delta=delta)
    assert p.chi == pytest.approx(chi, rel=0.01)
    assert p.S == pytest.approx(S, rel=0.01)


def test_groups_definitions():
    p = Params()
    assert p.chi == pytest.approx(p.gamma_dot * p.mu * p.R**3 / p.kappa)
    assert p.Re == pytest.approx(p.gamma_dot * p.rho * p.R**2 / p.mu)
    assert p.dt_gamma == pytest.approx(1e-7)
    assert p.dt_tau * p.chi == pytest.approx(p.dt_gamma)
    assert p.rho_bar * p.chi == pytest.approx(p.Re)
    assert chi_from_S(S_from_chi(12.3, 0.5), 0.5) == pytest.approx(12.3)
    # Table III: L / dx = 512
    assert p.L / 1.7578e-7 == pytest.approx(512, rel=1e-3)
    q = Params(Lambda=1e-9)
    assert q.Lambda_bar == pytest.approx(1e-9 * p.R**2 / p.kappa)


@pytest.mark.parametrize("field, value", [("R", -1.0), ("R", 0.0), ("mu", -1e-3), ("delta", 0.0), ("L", 1e-6)])
def test_bad_params_name_field(field, value):
    with pytest.raises(ConfigError, match=field):
        Params(**{field: value})
    assert math.isfinite(Params().S)
