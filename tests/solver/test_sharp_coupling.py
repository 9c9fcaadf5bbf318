"""The sharpened coupling (``coupling: sharp``): the kernel's Fourier transform, the window-deconvolution symbol,
the Stokes solver's force filter, and the coupled mobility it makes (symmetric, positive, Oseen in the far field).

Every check is against mathematics independent of the code under test: Parseval's theorem and a brute-force
quadrature for phi_hat, the unfiltered solver applied to a filtered force for the filter, the periodic Oseen tensor
(Ewald) for the pair mobility, and the definition of a symmetric positive semi-definite operator for M.
"""

import numpy as np
import pytest
from unit_run import unit_run

from vesicle_core.errors import ConfigError
from vesicle_core.solver.backend import get_backend
from vesicle_core.solver.ibm import Coupler, Grid
from vesicle_core.solver.kernels import KERNELS, phi_hat, phi_kernel, sharpening_symbol, window_symbol_1d
from vesicle_core.solver.mobility import IBMMobility
from vesicle_core.solver.stokes import StokesSolver

SUM_SQUARES = {"peskin4": 3 / 8, "roma3": 1 / 2}  # sum_j phi(r - j)^2, the same for every r (kernels.py)


@pytest.mark.parametrize("kernel", list(KERNELS))
def test_phi_hat_is_the_fourier_transform_of_the_kernel(kernel):
    theta = np.array([0.0, 0.3, 1.0, 2.0, np.pi, 5.0])
    r = np.linspace(-3.5, 3.5, 700001)
    brute = np.array([np.trapezoid(phi_kernel(r, kernel) * np.cos(t * r), r) for t in theta])
    np.testing.assert_allclose(phi_hat(theta, kernel), brute, rtol=0, atol=1e-9)
    assert phi_hat(0.0, kernel) == pytest.approx(1.0, abs=1e-13)  # the kernel integrates to one


@pytest.mark.parametrize("kernel", list(SUM_SQUARES))
def test_phi_hat_obeys_parseval(kernel):
    # int phi^2 dr = (1/2 pi) int phi_hat^2 dtheta, and int phi^2 = the r-average of sum_j phi(r - j)^2
    theta = np.linspace(-80.0, 80.0, 320001)
    assert np.trapezoid(phi_hat(theta, kernel) ** 2, theta) / (2 * np.pi) == pytest.approx(SUM_SQUARES[kernel],
                                                                                            rel=1e-6)


def test_sharpening_symbol_range_and_floor():
    N = 16
    W = sharpening_symbol(N, "peskin4", 0.05)
    assert W.shape == (N, N, N // 2 + 1)
    assert W[0, 0, 0] == pytest.approx(1.0)
    assert W.min() >= 1.0 - 1e-12 and W.max() == pytest.approx(1 / 0.05)  # peskin4's phi_hat(pi) = 0
    w1 = window_symbol_1d(N, "peskin4")
    # where phi_hat^2 is above the floor, W undoes it exactly
    p2 = (w1[:, None, None] * w1[None, :, None] * w1[None, None, : N // 2 + 1]) ** 2
    above = p2 > 0.05
    np.testing.assert_allclose((W * p2)[above], 1.0, rtol=1e-12)
    np.testing.assert_array_equal(sharpening_symbol(N, "peskin4", 1.0), np.ones_like(W))
    with pytest.raises(ValueError, match="sharp_floor"):
        sharpening_symbol(N, "peskin4", 0.0)
    assert not window_symbol_1d(N, "peskin4").flags.writeable  # cached: nobody may change it


def _filtered(f, W):
    F = np.fft.rfftn(f, axes=(1, 2, 3))
    return np.fft.irfftn(F * W[None], s=f.shape[1:], axes=(1, 2, 3))


@pytest.mark.parametrize("interleave,fused", [(None, None), (None, False), (False, None)])
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_force_filter_filters_the_force_and_nothing_else(interleave, fused, dtype):
    g = Grid(16, 5.0)
    be = get_backend("numpy", dtype) if interleave is None else get_backend("numpy", dtype, fft_library="numpy")
    W = sharpening_symbol(16, "peskin4", 0.02)
    rng = np.random.default_rng(1)
    f = rng.standard_normal(g.field_shape)
    tol = 1e-12 if dtype == "float64" else 2e-5
    sharp = StokesSolver(g, be, interleave=interleave, fused=fused, force_filter=W)
    plain = StokesSolver(g, be, interleave=interleave, fused=fused)
    ref = plain.velocity(_filtered(f, W).astype(dtype))
    assert np.abs(sharp.velocity(f.astype(dtype)) - ref).max() <= tol * np.abs(ref).max()
    # finite density (eq. 23): the filter acts on the force; the fluid's own decay is untouched
    sharp_u = StokesSolver(g, be, rho_bar=1e-3, interleave=interleave, force_filter=W)
    plain_u = StokesSolver(g, be, rho_bar=1e-3, interleave=interleave)
    for _ in range(3):
        a = sharp_u.step(f.astype(dtype), 2e-3)
        b = plain_u.step(_filtered(f, W).astype(dtype), 2e-3)
        assert np.abs(a - b).max() <= tol * np.abs(b).max()


def test_force_filter_rejects_bad_symbols():
    g, be = Grid(8, 5.0), get_backend("numpy")
    with pytest.raises(ConfigError, match="force_filter must have shape"):
        StokesSolver(g, be, force_filter=np.ones((8, 8, 8)))
    bad = np.ones((8, 8, 5))
    bad[1, 2, 3] = -1.0
    with pytest.raises(ConfigError, match="positive"):
        StokesSolver(g, be, force_filter=bad)


def _dense_mobility(kernel, floor, n=24, N=16, seed=3):
    g, be = Grid(N, 5.0), get_backend("numpy")
    mob = IBMMobility(Coupler(g, be, kernel=kernel), StokesSolver(g, be, force_filter=sharpening_symbol(N, kernel,
                                                                                                       floor)))
    X = np.random.default_rng(seed).uniform(0, 5.0, (n, 3))
    mob.prepare(X)
    M = np.empty((3 * n, 3 * n))
    for j in range(3 * n):
        e = np.zeros(3 * n)
        e[j] = 1.0
        M[:, j] = mob.apply(e.reshape(n, 3)).ravel()
    return M


@pytest.mark.parametrize("kernel", list(KERNELS))
def test_sharp_mobility_is_symmetric_positive_semidefinite(kernel):
    M = _dense_mobility(kernel, 0.01)
    assert np.abs(M - M.T).max() <= 1e-12 * np.abs(M).max()
    ev = np.linalg.eigvalsh(0.5 * (M + M.T))
    assert ev.min() >= -1e-12 * ev.max()
    rng = np.random.default_rng(0)
    for _ in range(5):
        x = rng.standard_normal(M.shape[0])
        assert x @ M @ x > 0.0


def test_sharp_mobility_is_larger_than_the_kernels():
    # W >= 1 everywhere, so F . M F can only grow: the sharpened Stokeslet is the kernel's with less smoothing
    rng = np.random.default_rng(2)
    g, be = Grid(16, 5.0), get_backend("numpy")
    X = rng.uniform(0, 5.0, (30, 3))
    F = rng.standard_normal((30, 3))
    out = []
    for W in (None, sharpening_symbol(16, "peskin4", 0.01)):
        mob = IBMMobility(Coupler(g, be), StokesSolver(g, be, force_filter=W))
        mob.prepare(X)
        out.append(float(np.sum(F * mob.apply(F))))
    assert out[1] > out[0] > 0.0


def test_sharp_pair_mobility_is_oseen_in_the_far_field():
    from vesicle_core.validation.stokeslet import stokeslet_report

    rep = stokeslet_report("peskin4", "sharp", 0.01, N=32, r=(8, 10), n_positions=4)
    # error in units of the Stokeslet's size 1/(8 pi r): a few per cent at 8-10 h (1.2-1.8 % at N = 64)
    assert max(rep.oseen_error) < 0.05
    # its hydrodynamic radius is well below the kernel's 1.25 h: less smearing of the membrane
    assert rep.a_h < 0.7
    kern = stokeslet_report("peskin4", "kernel", N=32, r=(8, 10), n_positions=4)
    assert 1.1 < kern.a_h < 1.4


def test_run_parameters_check_the_coupling():
    from vesicle_core.model.run_config import PAPER_METHOD, RunConfig

    with pytest.raises(ConfigError, match="coupling"):
        unit_run(coupling="spectral")
    with pytest.raises(ConfigError, match="sharp_floor"):
        unit_run(coupling="sharp", sharp_floor=0.0)
    assert RunConfig().coupling == "sharp"  # the recommended method's coupling is the default
    assert PAPER_METHOD["coupling"] == "kernel"  # the paper's is a named set


def test_sharp_coupling_resolves_more_modes_per_grid_node():
    """The clean-interface relaxation rate of Y_l0 against Lamb's theory (vesicle_core.validation.relaxation) at N =
    32, mesh
    edge h: the sharp coupling keeps l <= 6 within 5% (measured 0.953-0.991), the kernel's rate is already 23% slow at
    l = 3 and 57% at l = 6 (l h = 0.94: exp(-(l h / 1.04)^2) = 0.44)."""
    from vesicle_core.validation.relaxation import resolution_table

    ls = (2, 3, 4, 6, 8)
    sharp = resolution_table([32], ls, coupling="sharp", sharp_floor=0.01, edge=1.0)[32]
    kern = resolution_table([32], ls, coupling="kernel", edge=1.0)[32]
    assert sharp["n_vertices"] == kern["n_vertices"] == 596
    assert sharp["l_res"] >= 6
    assert kern["ratios"][3] < 0.85 and kern["ratios"][6] < 0.5
    assert all(sharp["ratios"][l] > kern["ratios"][l] for l in ls)


def test_sharp_mode_damping_describes_the_measured_rates():
    """kernels.mode_damping(coupling="sharp") (fitted at N = 64-192) against a fresh measurement at N = 32, a grid
    outside the fit: the adaptive step relies on it to know which wrinkles the grid can grow."""
    from vesicle_core.model.resolution import mode_damping
    from vesicle_core.validation.relaxation import resolution_table

    ls = (6, 8, 10)
    tab = resolution_table([32], ls, coupling="sharp", sharp_floor=0.01, edge=1.0)[32]
    for l in ls:
        assert tab["ratios"][l] / mode_damping(l, 5.0 / 32, coupling="sharp") == pytest.approx(1.0, abs=0.06)
    # and the kernel coupling's fit would be far off: the two couplings need their own damping
    assert tab["ratios"][10] / mode_damping(10, 5.0 / 32) > 2.0


def test_a_sharp_run_on_coarse_markers_or_the_3_point_kernel_warns(caplog):
    from vesicle_core.geometry import mesh as M
    from vesicle_core.solver.simulate import _check_mesh_spacing

    m = M.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))  # mean edge ~0.25 R
    with caplog.at_level("WARNING", logger="vesicle_core.solver.simulate"):
        _check_mesh_spacing(m, unit_run(N=16, coupling="sharp"))  # h = 0.31: edge < h, silent
        assert not caplog.records
        _check_mesh_spacing(m, unit_run(N=48, coupling="sharp"))  # h = 0.10: edge ~2.4 h
        assert "mesh edge" in caplog.text and "vertices" in caplog.text
        caplog.clear()
        _check_mesh_spacing(m, unit_run(N=16, coupling="sharp", kernel="roma3"))
        assert "roma3" in caplog.text
        caplog.clear()
        _check_mesh_spacing(m, unit_run(N=48))  # the kernel coupling has no such requirement
        assert not caplog.records


def test_inextensible_rates_with_the_sharp_coupling_follow_the_clean_interface_only_in_the_harmonic_space():
    """Gamma_l of eq. (11) at N = 32, mesh edge h, sharp coupling: under the harmonic tension the constrained rate over
    theory tracks the clean interface's ratio on the same grid (measured 0.975, 0.961, 0.947 at l = 3, 4, 6 against
    1.005, 1.006, 0.953); the per-triangle tension locks on this mesh (0.836, 0.784, 0.699)."""
    from vesicle_core.validation.relaxation import mode_rate

    kw = {"coupling": "sharp", "sharp_floor": 0.01, "cg_tol": 1e-6}
    for l in (3, 4, 6):
        clean = mode_rate(l, 32, 596, **kw).ratio
        harm = mode_rate(l, 32, 596, membrane="inextensible", tension_space="harmonic", **kw).ratio
        assert abs(harm - clean) < 0.05, (l, harm, clean)
    assert mode_rate(6, 32, 596, membrane="inextensible", tension_space="triangle", **kw).ratio < 0.8
