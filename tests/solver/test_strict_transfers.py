"""Host-device transfers per step on the device path, counted by the strict CuPy stand-in (tests/strict_cupy.py).

A step's transfers are of two kinds. Per Stokes product of the harmonic tension's CG (and its warm-start and drift
solves): the coefficients go to the device and the area rate's projection comes back (K = (l_t + 1)^2 numbers
each; B lives on the device), 2 per product; the product count follows the CG's iterations, not the mesh. The rest is a
fixed budget per step (measured on these cases, 162 and 642 vertices alike): the tension's warm start and result,
the linearisation strain and the mesh ALE (host LSQR: positions, displacement and area error down, the tangential
displacement up), the noise field (lm: one 3 N^3 host draw up; midpoint: two), the frame's scalars.

Measured (d2h + h2d - 2 x Stokes products per step; scalar reads per step), 162 and 642 vertices at N = 16:
default job 17-19 (scalars 8-10); noise lm + secant 20-21; noise midpoint + secant 23-25. BUDGET is the largest of
those: a new transfer per step, or one that grows with the vertex count, fails here and must be justified by
raising the budget deliberately.
"""

from __future__ import annotations

import numpy as np
import pytest

from vesicle_core.geometry import mesh as M

#: transfers per step beyond 2 per Stokes product, and synchronising scalar reads per step (module docstring)
BUDGET = {"default_job": 19, "noise_lm_secant": 21, "noise_midpoint_secant": 25}
SCALAR_BUDGET = 10


def per_step_transfers(cp, monkeypatch, tmp_path, case, level):
    """Run ``case`` on the stand-in with an icosphere of ``level`` -> per loop iteration (step) the dict of counts,
    with 'products' the Stokes products and 'extra' = d2h + h2d - 2 products."""
    import test_strict_gpu_path as T

    from vesicle_core.solver import simulate

    per, last = [], [None]
    events = simulate._Run._events

    def counted_events(self, *args, **kwargs):
        now = {**cp.transfers.snapshot(), "products": self.integ.mobility.n_products}
        if last[0] is not None:
            d = {k: now[k] - last[0][k] for k in now}
            d["extra"] = d["d2h"] + d["h2d"] - 2 * d["products"]
            per.append(d)
        last[0] = now
        return events(self, *args, **kwargs)

    m = M.make_vesicle("icosphere", level=level, axes=(1.0, 0.8, 1.0))
    with monkeypatch.context() as mp:
        mp.setattr(simulate._Run, "_events", counted_events)
        T.run_case(tmp_path / f"{case}-{level}", T.config(case, "cupy", cg_tol=1e-5, cg_maxiter=200), m)
    assert len(per) >= 3
    return per


def check_bounded(case, counts):
    """counts: {n_vertices: per-step list}. Every step within the budget, and the same worst step at every size."""
    worst = {}
    for n, per in counts.items():
        extra = max(p["extra"] for p in per)
        scalars = max(p["scalar_reads"] for p in per)
        assert extra <= BUDGET[case], f"{case}, {n} vertices: {extra} transfers per step beyond the CG's " \
                                      f"(budget {BUDGET[case]})"
        assert scalars <= SCALAR_BUDGET, f"{case}, {n} vertices: {scalars} scalar reads per step"
        worst[n] = extra
    assert len(set(worst.values())) == 1, f"{case}: transfers per step change with the vertex count: {worst}"


@pytest.mark.parametrize("case", list(BUDGET))
def test_strict_transfers_per_step_are_bounded_and_independent_of_vertices(strict_cupy, monkeypatch, tmp_path, case):
    counts = {n: per_step_transfers(strict_cupy, monkeypatch, tmp_path, case, level)
              for n, level in ((162, 2), (642, 3))}
    for n, per in counts.items():
        print(case, n, [(p["d2h"], p["h2d"], p["scalar_reads"], p["products"]) for p in per])
    check_bounded(case, counts)


def test_strict_planted_host_copy_per_step_fails_the_bound(strict_cupy, monkeypatch, tmp_path):
    """Must show: a per-step copy of the positions to the host (what the thermal drift's random finite difference
    made before) breaks the budget."""
    from vesicle_core.solver.integrators import Inextensible

    step = Inextensible.step

    def step_with_host_copy(self, state, X, *args, **kwargs):
        self.solver.be.asnumpy(X)
        return step(self, state, X, *args, **kwargs)

    monkeypatch.setattr(Inextensible, "step", step_with_host_copy)
    counts = {n: per_step_transfers(strict_cupy, monkeypatch, tmp_path, "default_job", level)
              for n, level in ((162, 2), (642, 3))}
    with pytest.raises(AssertionError, match="transfers per step beyond"):
        check_bounded("default_job", counts)


def test_strict_planted_per_vertex_host_loop_fails_the_bound(strict_cupy, monkeypatch, tmp_path):
    """A per-vertex host loop (a scalar read per vertex) breaks both the budget and the independence of V."""
    from vesicle_core.solver.integrators import Inextensible
    from vesicle_core.xp import to_float

    step = Inextensible.step

    def step_with_loop(self, state, X, *args, **kwargs):
        for i in range(X.shape[0]):
            to_float(X[i, 0])
        return step(self, state, X, *args, **kwargs)

    monkeypatch.setattr(Inextensible, "step", step_with_loop)
    counts = {n: per_step_transfers(strict_cupy, monkeypatch, tmp_path, "default_job", level)
              for n, level in ((162, 2), (642, 3))}
    with pytest.raises(AssertionError, match="scalar reads per step"):
        check_bounded("default_job", counts)


def test_strict_planted_numpy_call_in_spread_raises(strict_cupy, monkeypatch):
    """Must show: ``np.sum`` on a device array inside ibm.spread (an implicit conversion) raises on the stand-in,
    while the unplanted spread runs and conserves the force."""
    from vesicle_core.solver import ibm
    from vesicle_core.solver.backend import get_backend

    be = get_backend("cupy")
    grid = ibm.Grid(16, 5.0)
    rng = np.random.default_rng(0)
    X = strict_cupy.asarray(rng.uniform(-1, 1, (20, 3)))
    F = strict_cupy.asarray(rng.standard_normal((20, 3)))
    st = ibm.prepare(X, grid, be)
    f = ibm.spread(F, st, grid, be)
    total = strict_cupy.asnumpy(f.sum(axis=(1, 2, 3))) * grid.h**3
    np.testing.assert_allclose(total, strict_cupy.asnumpy(F.sum(axis=0)), rtol=1e-12)

    scatter = ibm._scatter

    def planted(F, stencil, grid, backend, out, work=None):
        np.sum(F)  # the planted implicit conversion
        return scatter(F, stencil, grid, backend, out, work)

    monkeypatch.setattr(ibm, "_scatter", planted)
    with pytest.raises(TypeError, match="device array"):
        ibm.spread(F, st, grid, be)


def _scipy_norm(a):
    import scipy.linalg

    return scipy.linalg.norm(a)


@pytest.mark.parametrize("convert", [np.asarray, float, int, bool, lambda a: a.item(), lambda a: a + np.ones(1),
                                     lambda a: np.sqrt(a), lambda a: np.sum(a), _scipy_norm,
                                     lambda a: a[np.zeros(1, dtype=int)]])
def test_strict_stand_in_refuses_implicit_conversions(strict_cupy, convert):
    a = strict_cupy.asarray(np.ones(1))
    with pytest.raises(TypeError):
        convert(a)
    before = strict_cupy.transfers.snapshot()
    assert strict_cupy.asnumpy(a).shape == (1,) and a.get().shape == (1,)
    after = strict_cupy.transfers.snapshot()
    assert after["scalar_reads"] == before["scalar_reads"] + 2
