import numpy as np
import pytest

from vesicle_core.solver.kernels import delta3, phi, stencil


@pytest.mark.parametrize("r", np.random.default_rng(0).uniform(-3, 3, 25).tolist() + [0.0, 0.5, 1.0, 2.0])
def test_moments(r):
    j = np.arange(-6, 7)
    w = phi(r - j)
    assert w.sum() == pytest.approx(1.0, abs=1e-14)
    assert ((r - j) * w).sum() == pytest.approx(0.0, abs=1e-14)
    assert (w**2).sum() == pytest.approx(3.0 / 8.0, abs=1e-14)


def test_support_continuity_and_symmetry():
    r = np.linspace(-2.5, 2.5, 10001)
    p = phi(r)
    assert np.all(p[np.abs(r) >= 2] == 0)
    assert np.allclose(p, phi(-r))
    assert np.max(np.abs(np.diff(p))) < 1e-3  # continuous, including at |r| = 1 and 2
    assert phi(0.0) == pytest.approx(0.5)


def test_delta3_integrates_to_one():
    h = 0.1
    g = np.arange(-10, 11) * h
    x0 = np.array([0.013, -0.041, 0.07])
    Xg = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)
    assert delta3(Xg - x0, h).sum() * h**3 == pytest.approx(1.0, abs=1e-13)


def test_stencil_weights_and_periodic_indices():
    N, L = 16, 4.0
    h = L / N
    X = np.array([[-1.99, 0.3, 1.98], [0.0, 0.0, 0.0]])
    idx, w = stencil(X, h, N, origin=-L / 2)
    assert idx.min() >= 0 and idx.max() < N
    assert np.allclose(w.sum(-1), 1.0)
    # node m sits at -L/2 + m h: the weight of each node equals phi of its distance in grid units
    xm = -L / 2 + idx * h
    d = X[..., None] - xm
    d = (d + L / 2) % L - L / 2  # periodic distance
    assert np.allclose(w, phi(d / h))


@pytest.mark.parametrize("kernel, width, sumsq", [("roma3", 3, 0.5), ("peskin4", 4, 3.0 / 8.0), ("bao6", 6, None)])
def test_every_kernel_partitions_unity_with_zero_first_moment(kernel, width, sumsq):
    from vesicle_core.solver.kernels import KERNELS, phi_kernel

    assert KERNELS[kernel] == width
    rng = np.random.default_rng(4)
    X = rng.uniform(-1.0, 1.0, (200, 3))
    h, N, origin = 0.1, 32, -1.6
    idx, w = stencil(X, h, N, origin, kernel=kernel)
    assert idx.shape == (200, 3, width)
    s = (X - origin) / h
    d = ((idx - s[..., None] + N / 2) % N) - N / 2  # signed distance node - point, in h
    np.testing.assert_allclose(w.sum(-1), 1.0, atol=1e-13)
    np.testing.assert_allclose((d * w).sum(-1), 0.0, atol=1e-13)
    assert w.min() >= 0.0
    sq = (w**2).sum(-1)
    if sumsq is not None:
        np.testing.assert_allclose(sq, sumsq, atol=1e-13)
    else:  # Bao-Kaye-Peskin: constant sum of squares and vanishing second and third moment deviations
        np.testing.assert_allclose(sq, sq.flat[0], atol=1e-13)
        np.testing.assert_allclose((d**3 * w).sum(-1), 0.0, atol=1e-12)
        np.testing.assert_allclose((d**2 * w).sum(-1), (d**2 * w).sum(-1).flat[0], atol=1e-12)
    # the stencil weights are the kernel evaluated at the node distances
    np.testing.assert_allclose(w, phi_kernel(d, kernel), atol=1e-13)
    # and the kernel integrates to one
    r = np.linspace(-3.5, 3.5, 7001)
    assert abs(phi_kernel(r, kernel).sum() * (r[1] - r[0]) - 1.0) < 1e-6


def test_wider_kernels_smear_modes_more():
    from vesicle_core.model.resolution import mode_damping

    d = [mode_damping(10, 0.05, k) for k in ("roma3", "peskin4", "bao6")]
    assert d[0] > d[1] > d[2]
