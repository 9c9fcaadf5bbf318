"""A step's cost beside its Stokes products (issue 48, item 5): the faster paths give the old paths' bits, or, where
the arithmetic changed on purpose, stay within the rounding the run already has.

Each test runs the new code and the arithmetic it replaced, kept here as the reference, on the same input: the
G solves must agree to the last bit, and so must a few steps of the default discretisation (inextensible scheme,
harmonic tension, quality mesh ALE, sharp coupling, bao6 kernel, float32 grid) with the reference put back in.
The tension solve's basis products in float32 (float32 grids only) change the default job's bits: those steps are
compared with float64 products, against what a float64 grid changes on the same steps.
The timings themselves are in benchmarks/bench_step_cost.py, never in a test."""

import tempfile
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sl

from vesicle_core.geometry import mesh as Mm
from vesicle_core.model.run_config import RunConfig
from vesicle_core.solver import tension_harmonic as th
from vesicle_core.solver.simulate import _Run

DEFAULT_JOB = dict(chi=66.7, N=16, L=5.0, scheme="inextensible", tension_space="harmonic", mesh_ale="quality",
                   coupling="sharp", kernel="bao6", seed_spectrum="thermal", dtype="float32", stretch=0.01,
                   t_end=1.0, output_every=0.02, fft_workers=1, checkpoint_every=10_000)


def _old_G_solve(space, r):
    """HarmonicSpace.G_solve before: the C-ordered factor, both arrays checked for NaN on every call."""
    return sl.cho_solve((np.ascontiguousarray(space.G_chol), True), r)


@pytest.fixture(scope="module")
def space():
    m = Mm.make_vesicle("quasiuniform", n_vertices=642, axes=(1.0, 0.8, 1.0))
    from vesicle_core.solver import membrane as B

    geo = B.geometry(m.vertices, B.Topology(m.faces, m.n_vertices))
    return th.HarmonicSpace(m.vertices, m.faces, geo.area)


def test_the_G_solve_gives_the_bits_of_the_C_ordered_factor(space):
    assert space.G_chol.flags.f_contiguous  # what potrs reads in place
    rng = np.random.default_rng(3)
    for _ in range(5):
        r = rng.standard_normal(space.K) * 10.0 ** rng.uniform(-6, 6)
        np.testing.assert_array_equal(space.G_solve(r), _old_G_solve(space, r))
    # it solves G x = r (a fast path that returned garbage would still have to pass this)
    r = rng.standard_normal(space.K)
    np.testing.assert_allclose(space.G @ space.G_solve(r), r, rtol=0, atol=1e-10 * np.abs(r).max())


def test_a_NaN_right_hand_side_is_still_refused(space):
    r = np.zeros(space.K)
    r[1] = np.nan
    with pytest.raises(ValueError):
        space.G_solve(r)


def _steps(n_steps, monkeypatch=None, basis64=False, **changes):
    """Positions and tensions after each of n_steps steps of the default discretisation on a small case (the
    flow reversed and the thermal seed laid within them). ``monkeypatch``: with the old G solve; ``basis64``: with
    the tension solve's basis products in float64."""
    m = Mm.make_vesicle("quasiuniform", n_vertices=642, axes=(1.0, 0.8, 1.0))
    cfg = RunConfig(**{**DEFAULT_JOB, **changes})
    X, sigma = [], []
    with tempfile.TemporaryDirectory() as d:
        r = _Run(m, cfg, Path(d), False)
        assert r.integ.tension._B.dtype == np.dtype(cfg.dtype)  # the products in the grid's precision
        if monkeypatch is not None:
            space = r.integ.space
            monkeypatch.setattr(space, "G_solve", lambda v: _old_G_solve(space, v))
        if basis64:
            r.integ.tension._B = r.integ.space.B
        for k in range(n_steps):
            r.loop(k + 1)
            X.append(np.asarray(r.state.X).copy())
            sigma.append(np.asarray(r.state.sigma).copy())
        phase = r.state.phase
    return np.array(X), np.array(sigma), phase


def test_steps_of_the_default_discretisation_keep_their_bits(monkeypatch):
    X_new, s_new, phase = _steps(24)
    assert phase == "relax"  # the steps cross the reversal, and a bending-limit measurement (step 20)
    X_old, s_old, _ = _steps(24, monkeypatch)
    assert np.abs(X_new[-1] - X_new[0]).max() > 0  # the vesicle moved
    np.testing.assert_array_equal(X_new, X_old)
    np.testing.assert_array_equal(s_new, s_old)


def test_float32_basis_products_move_the_steps_no_more_than_a_float64_grid():
    """The default job's float32 grid rounds every Stokes product to ~1e-7; the products B c and B^T f in float32
    round the tension as much. Over 24 steps (the CG's tolerance lets any rounding grow to ~1e-6 of a step's
    displacement), they must move positions and tensions no more than the float64 grid does, and far less than the
    steps themselves."""
    X, s, _ = _steps(24)
    X64b, s64b, _ = _steps(24, basis64=True)
    X64g, s64g, _ = _steps(24, dtype="float64")  # the float64 grid, with float64 products
    moved = np.abs(X[-1] - X[0]).max()
    d_basis, d_grid = np.abs(X - X64b).max(), np.abs(X64g - X64b).max()
    ds_basis, ds_grid = np.abs(s - s64b).max(), np.abs(s64g - s64b).max()
    assert d_basis > 0  # a float32 product, not a float64 one in disguise
    assert d_basis <= max(2.0 * d_grid, 1e-6 * moved), (d_basis, d_grid, moved)
    assert ds_basis <= max(2.0 * ds_grid, 1e-6 * np.abs(s64b).max()), (ds_basis, ds_grid)
