"""The mesh's energy of a shape mode against the continuum's, and the equilibrium spectrum it implies."""

import numpy as np
import pytest

from vesicle_core.geometry.mesh import icosphere
from vesicle_core.validation.mode_energy import continuum_spectrum, equilibrium_spectrum, mode_stiffness

KT, DELTA = 0.0405, 0.04


@pytest.fixture(scope="module")
def meshes():
    return {lev: icosphere(lev) for lev in (2, 3)}


def test_mode_stiffness_tends_to_the_continuum_like_h2(meshes):
    coarse, fine = (mode_stiffness(*meshes[lev], l_max=4) for lev in (2, 3))
    for name in ("area", "bending"):
        d_coarse, d_fine = 1 - getattr(coarse, name), 1 - getattr(fine, name)
        # the piecewise-flat surface makes every mode cheaper than the continuum, and halving the edge cuts
        # the deficit ~4x (second order)
        assert np.all(d_coarse > 0) and np.all(d_fine > 0), name
        assert np.all((d_coarse / d_fine > 3.0) & (d_coarse / d_fine < 5.0)), (name, d_coarse / d_fine)
    # at l = 2 the 642-vertex sphere's area is within 1% and its bending energy within 5% of the continuum
    assert abs(1 - fine.area[0]) < 0.01 and abs(1 - fine.bending[0]) < 0.05


@pytest.mark.parametrize("sigma", [0.0, 600.0])
def test_equilibrium_spectrum_is_the_inverse_of_the_mode_stiffness(meshes, sigma):
    X, f = meshes[2]
    spec, p = equilibrium_spectrum(X, f, sigma, KT, 4, DELTA)
    # the sphere's pressure balances its tension: Laplace, 2 sigma (R = 1)
    assert p == pytest.approx(2 * sigma, rel=0.02, abs=0.1)
    # l = 2 is nearly an eigenvector of the mesh's energy: its variance is kT over the stiffness measured along
    # the mode by energy differences (an independent path: no Hessian, no estimator)
    ms = mode_stiffness(X, f, 2)
    l = 2
    stiff = (l - 1) * (l + 2) * (ms.bending[0] * l * (l + 1) + ms.area[0] * sigma)
    expected = KT * (l - 1) * (l + 2) / (DELTA * stiff)
    assert spec[2] == pytest.approx(expected, rel=0.015)
    # and both lie above the continuum (the coarse mesh is softer)
    assert spec[2] > continuum_spectrum(2, sigma, KT, DELTA)
