"""The inextensible scheme: the tension operator (symmetry, positivity, exact gradients), the PCG solve
(linearised constraint met, failure is loud), and whole runs (area held, resume identical)."""

import numpy as np
import pytest
import xarray as xr
from unit_run import unit_run

from vesicle_core.errors import NumericalInstability
from vesicle_core.geometry import mesh as Mm
from vesicle_core.solver import membrane as B
from vesicle_core.solver.mobility import IBMMobility, IBMSolver
from vesicle_core.solver.simulate import run
from vesicle_core.solver.tension import (
    TensionSolver,
    cell_areas,
    dual_areas,
    face_D,
    face_DT,
    vertex_D,
    vertex_DT,
    vertex_mean,
)
from vesicle_core.solver.trajectory import CHECKPOINT, FAILURE, TRAJECTORY, TrajectoryWriter


@pytest.fixture(scope="module")
def setup():
    m = Mm.make_vesicle("quasiuniform", n_vertices=162, axes=(1.0, 0.8, 1.0))
    cfg = unit_run(chi=50.0, N=16, scheme="inextensible")
    s = IBMSolver(m.faces, m.vertices, cfg)
    X = s.xp.asarray(m.vertices)
    F, geo = s.forces(X)
    mob = IBMMobility(s.coupler, s.stokes)
    mob.prepare(X)
    return m, s, X, F, geo, mob


def _flat_lattice(n=8, a=0.1):
    """A flat patch of the regular triangular lattice: vertices, faces, and +1 / -1 on up / down triangles."""
    idx = {(i, j): i + n * j for j in range(n) for i in range(n)}
    X = a * np.array([(i + 0.5 * j, j * np.sqrt(3) / 2, 0.0) for j in range(n) for i in range(n)])
    faces, sign = [], []
    for j in range(n - 1):
        for i in range(n - 1):
            p, q, r, s = idx[(i, j)], idx[(i + 1, j)], idx[(i, j + 1)], idx[(i + 1, j + 1)]
            faces += [(p, q, r), (q, s, r)]
            sign += [1.0, -1.0]
    interior = [idx[(i, j)] for j in range(1, n - 1) for i in range(1, n - 1)]
    return X, np.array(faces), np.array(sign), interior


def test_tension_force_is_marangoni_and_the_checkerboard_is_force_free():
    """-D^T sigma of a linear tension is its gradient times the dual-cell area (the Marangoni force, pulling
    towards higher tension); a tension alternating between up and down triangles exerts no force at all on the
    interior of a regular lattice (each set of alternate hexagon edges sums to zero). That null mode is why the
    solved tension carries a mesh-scale checkerboard that the vertex motion cannot hold down
    (docs/history/solver.md)."""
    X, faces, sign, interior = _flat_lattice()
    topo = B.Topology(faces, len(X))
    geo = B.geometry(X, topo)
    grad = np.array([3.0, -2.0, 0.0])
    sigma = X[faces].mean(axis=1) @ grad
    force = -face_DT(sigma, geo, topo)[interior]
    assert np.allclose(force, dual_areas(geo, topo)[interior, None] * grad, rtol=0, atol=1e-14)
    uniform = np.abs(face_DT(np.ones(len(faces)), geo, topo)).max()  # boundary vertices: the patch's edge pull
    assert np.abs(face_DT(sign, geo, topo)[interior]).max() <= 1e-14 * uniform
    # an irregular lattice breaks the cancellation only to first order in its irregularity
    d = np.random.default_rng(0).standard_normal(X.shape) * [1, 1, 0]
    f1, f2 = (np.linalg.norm(face_DT(sign, B.geometry(X + e * d, topo), topo)[interior]) for e in (1e-5, 2e-5))
    assert 0 < f1 and f2 / f1 == pytest.approx(2.0, rel=1e-3)


@pytest.mark.parametrize("cells", ["face", "vertex"])
def test_operator_symmetric_and_positive(setup, cells):
    _, s, _, _, geo, mob = setup
    topo = s.membrane.topo
    ts = TensionSolver(mob, topo, cell_areas(geo, topo, cells), 1e6, cells=cells)
    rng = np.random.default_rng(1)
    n = ts.A0.shape[0]
    for _ in range(3):
        u, v = rng.standard_normal(n), rng.standard_normal(n)
        Au, _ = ts.operator(u, geo, 1e-4)
        Av, _ = ts.operator(v, geo, 1e-4)
        assert abs(v @ Au - u @ Av) <= 1e-12 * abs(v @ Au)  # symmetric to round-off
        assert u @ Au > 0 and v @ Av > 0
        # positive beyond the compliance alone: the mobility part is positive semi-definite
        assert u @ Au - u @ (ts.A0 * u) / ts.Lambda >= -1e-12 * (u @ Au)


@pytest.mark.parametrize("D, DT, areas", [(face_D, face_DT, lambda g, t: g.area), (vertex_D, vertex_DT, dual_areas)])
def test_DT_is_the_gradient_of_the_cell_areas(setup, D, DT, areas):
    _, s, X, _, geo, _ = setup
    topo = s.membrane.topo
    rng = np.random.default_rng(2)
    sig = rng.standard_normal(areas(geo, topo).shape[0])
    dX = rng.standard_normal(X.shape)
    eps = 1e-6

    def energy(Y):
        return float(sig @ areas(B.geometry(Y, topo), topo))

    fd = (energy(X + eps * dX) - energy(X - eps * dX)) / (2 * eps)
    assert fd == pytest.approx(float(np.sum(DT(sig, geo, topo) * dX)), rel=1e-7)
    # D is the adjoint of D^T
    assert float(sig @ D(dX, geo, topo)) == pytest.approx(float(np.sum(DT(sig, geo, topo) * dX)), rel=1e-12)


def test_solve_meets_the_linearised_constraint(setup):
    _, s, X, F, geo, mob = setup
    topo = s.membrane.topo
    Lam, dt = 1e6, 2e-4
    ts = TensionSolver(mob, topo, geo.area.copy(), Lam, tol=1e-10, maxiter=500)
    u_inf = s.xp.asarray(np.c_[X[:, 0], -X[:, 1], 0 * X[:, 2]] * 50.0)
    err = 1e-4 * np.random.default_rng(3).standard_normal(geo.area.shape[0]) * geo.area
    sigma, U = ts.solve(geo, F, u_inf, err, dt, np.zeros_like(err))
    # the returned velocity is the velocity of the returned tension
    U_direct = mob.apply(F - face_DT(sigma, geo, topo)) + u_inf
    assert np.abs(U - U_direct).max() <= 1e-8 * np.abs(U_direct).max()
    # linearised area after the step = compliance strain
    new_area_error = err + dt * face_D(U, geo, topo)
    assert np.sqrt(np.mean(((new_area_error - geo.area * sigma / Lam) / geo.area) ** 2)) <= 1e-10
    assert ts.last.iterations > 0


def test_unconverged_solve_raises(setup):
    _, s, _, F, geo, mob = setup
    ts = TensionSolver(mob, s.membrane.topo, geo.area.copy(), 1e7, tol=1e-14, maxiter=2)
    with pytest.raises(NumericalInstability, match="did not converge"):
        ts.solve(geo, F, 0.0, 0 * geo.area, 1e-3, 0 * geo.area)


def _run_cfg(**kw):
    base = {"chi": 50.0, "N": 16, "scheme": "inextensible", "stretch": 0.3, "t_end": 0.2, "output_every": 0.05}
    return unit_run(**{**base, **kw})


@pytest.fixture(scope="module")
def inext_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("inext")
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    return m, xr.open_dataset(run(m, _run_cfg(), d, progress=False)).load()


def test_inextensible_run_holds_every_triangle(inext_run):
    m, ds = inext_run
    X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
    topo = B.Topology(m.faces, m.n_vertices)
    a0 = B.geometry(X[0], topo).area
    lam = ds.attrs["Lambda_eff"]
    for k in range(X.shape[0]):
        g = B.geometry(X[k], topo)
        strain = g.area / a0 - 1
        # the strain is the compliance sigma / Lambda of the solved tension, nothing else
        assert np.abs(strain - ds.face_tension.values[k] / lam).max() < 2e-4
    assert ds.attrs["cg_iterations_max"] >= 1
    # frames at the configured instants, exactly: the adaptive step lands on them
    assert np.allclose(np.diff(ds.time.values), 0.05, atol=1e-9)
    # stretched in the forward flow: positive tension; after the reversal it turns negative
    assert ds.tension.sel(time=0.0, method="nearest") > 0
    assert ds.tension.values[-1] < ds.tension.sel(time=0.0, method="nearest")


@pytest.mark.parametrize(("space", "kT", "ale", "precond", "noise"),
                         [("triangle", 0.0, "none", "compliance", "lm"),
                          ("harmonic", 0.0, "none", "compliance", "lm"),
                          ("harmonic", 0.0, "shape", "compliance", "lm"),
                          ("harmonic", 0.0405, "none", "compliance", "lm"),
                          ("harmonic", 0.0405, "none", "secant", "lm"),
                          ("harmonic", 0.0405, "none", "secant", "midpoint"),
                          ("triangle", 0.0405, "none", "compliance", "midpoint")])
def test_inextensible_resume_is_identical(tmp_path, space, kT, ale, precond, noise):
    """A run stopped after 25 steps and resumed from its checkpoint (every 7 steps) gives the uninterrupted run's
    frames bit for bit. The harmonic tension checkpoints its measured diagonal rho_l and its age, and each
    measurement's draw is seeded by its step; the thermal noise and its drift draw from (noise_seed, step) only;
    mesh_ale shape checkpoints the lipid area the triangles carry; cg_precond secant its operator model and the last
    step's modelled noise response; the midpoint scheme its two half increments and its drift from the same keys."""
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    cfg = _run_cfg(checkpoint_every=7, tension_space=space, kT=kT, noise_seed=5, mesh_ale=ale, cg_precond=precond,
                   noise_scheme=noise)
    ref = xr.open_dataset(run(m, cfg, tmp_path / "a", progress=False)).load()
    # 25: past the bending limit's first re-measurement (step 20) and its checkpoint (21), so that the one at step
    # 40 starts from the checkpointed vector
    assert run(m, cfg, tmp_path / "b", progress=False, stop_after_steps=25) is None
    assert (tmp_path / "b" / CHECKPOINT).exists() and not (tmp_path / "b" / TRAJECTORY).exists()
    res = xr.open_dataset(run(m, cfg, tmp_path / "b", progress=False)).load()
    assert res.attrs["steps"] == ref.attrs["steps"]
    np.testing.assert_array_equal(res.node_x.values, ref.node_x.values)
    np.testing.assert_array_equal(res.face_tension.values, ref.face_tension.values)
    np.testing.assert_array_equal(res.dt_tau.values, ref.dt_tau.values)  # every frame's own step, resumed or not
    assert res.attrs["dt_bending_last_tau"] == ref.attrs["dt_bending_last_tau"]  # the step-40 re-measurement
    np.testing.assert_array_equal(res.triangle_strain_max.values, ref.triangle_strain_max.values)
    for name in TrajectoryWriter.LIMIT_VARS:  # the step-limit record: the counts since the checkpoint's frame too
        np.testing.assert_array_equal(res[name].values, ref[name].values, err_msg=name)


def test_thermal_seed_survives_a_resume_after_the_reversal(tmp_path):
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    cfg = _run_cfg(checkpoint_every=3, seed_spectrum="thermal")
    ref = xr.open_dataset(run(m, cfg, tmp_path / "a", progress=False)).load()
    assert ref.attrs["seed_l_max"] >= 3
    t_rev = ref.attrs["t_reverse_tau"]
    steps_to_reversal = int(np.searchsorted(np.cumsum(ref.dt_tau.values), t_rev))
    # stop after the reversal, so the resumed call never sees the seed being put on
    stop = max(steps_to_reversal, 1) + int(ref.attrs["steps"] - steps_to_reversal) // 2
    assert run(m, cfg, tmp_path / "b", progress=False, stop_after_steps=stop) is None
    res = xr.open_dataset(run(m, cfg, tmp_path / "b", progress=False)).load()
    assert res.attrs["seed_l_max"] == ref.attrs["seed_l_max"]
    np.testing.assert_array_equal(res.node_x.values, ref.node_x.values)


def test_failed_tension_solve_stops_the_run(tmp_path):
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    with pytest.raises(NumericalInstability, match="tension solve"):
        run(m, _run_cfg(cg_tol=1e-14, cg_maxiter=1), tmp_path, progress=False)
    assert (tmp_path / FAILURE).exists() and not (tmp_path / TRAJECTORY).exists()


def test_vertex_mean_of_uniform_is_uniform(setup):
    _, s, _, _, geo, _ = setup
    v = vertex_mean(np.full(geo.area.shape[0], 3.5), geo, s.membrane.topo)
    assert np.allclose(v, 3.5)


def _local_case(n_vertices):
    """A 1:0.8:1 ellipsoid at N = 32 with its local preconditioner (built before the stencil is prepared, since
    measuring the pair mobility replaces it) -> X, F, geo, mobility, topology, preconditioner, M_loc."""
    from vesicle_core.solver.mobility import local_mobility_matrix
    from vesicle_core.solver.tension import LocalPreconditioner

    m = Mm.make_vesicle("quasiuniform", n_vertices=n_vertices, axes=(1.0, 0.8, 1.0))
    s = IBMSolver(m.faces, m.vertices, unit_run(chi=268.0, N=32, scheme="inextensible"))
    X = s.xp.asarray(m.vertices)
    F, geo = s.forces(X)
    mob = IBMMobility(s.coupler, s.stokes)
    local = LocalPreconditioner(mob, s.membrane.topo, geo.area.copy(), 1.34e7)
    mob.prepare(X)
    return X, F, geo, mob, s.membrane.topo, local, local_mobility_matrix(m.vertices, local.table, r_cut=local.r_cut)


def _assembled_P(M_loc, geo, topo, dt, shift=0.0):
    """P = dt D (M_loc + shift I) D^T + W / Lambda as a dense matrix."""
    import scipy.sparse as sp

    from vesicle_core.solver.tension import face_D_matrix

    D = face_D_matrix(geo, topo)
    M = M_loc + shift * sp.identity(M_loc.shape[0])
    return (dt * (D @ M @ D.T) + sp.diags(geo.area / 1.34e7)).toarray()


def test_local_preconditioner_same_solution_fewer_iterations():
    X, F, geo, mob, topo, local, _ = _local_case(162)  # edge ~ 2h at N = 32
    u_inf = 268.0 * np.c_[-X[:, 0], X[:, 1], 0 * X[:, 2]]
    zero = np.zeros(geo.area.shape[0])
    out = {}
    for name, pre in (("compliance", None), ("local", local)):
        ts = TensionSolver(mob, topo, geo.area.copy(), 1.34e7, tol=1e-10, maxiter=1000, local=pre)
        sigma, _ = ts.solve(geo, F, u_inf, zero, 3.7e-5, zero)
        out[name] = (sigma, ts.last.iterations)
    (s_c, it_c), (s_l, it_l) = out["compliance"], out["local"]
    assert np.abs(s_l - s_c).max() <= 1e-3 * np.abs(s_c).max()  # the same system, solved either way
    assert it_l < 0.6 * it_c


def test_local_preconditioner_factorisation_solves_its_matrix(monkeypatch):
    """The symmetric-mode LU (no pivoting, a symmetric ordering) applies P^{-1} exactly: checked against a dense
    solve of the assembled P = dt D M_loc D^T + W / Lambda."""
    _, _, geo, _, topo, local, M_loc = _local_case(162)
    r = np.random.default_rng(1).standard_normal(geo.area.shape[0])
    z = local(r, geo, 3.7e-5)
    assert local.shift == 0.0  # the premise: M_loc is definite with margin on this mesh, so P is the plain one
    z_dense = np.linalg.solve(_assembled_P(M_loc, geo, topo, 3.7e-5), r)
    assert np.abs(z - z_dense).max() <= 1e-8 * np.abs(z_dense).max()
    assert local.factorisations == 1 and local.seconds > 0

    # a zero pivot in the symmetric mode (an indefinite P) falls back to the pivoting LU, same answer
    import scipy.sparse.linalg as spla

    calls = []
    real = spla.splu

    def splu(A, **kw):
        calls.append(kw)
        if kw.get("options", {}).get("SymmetricMode"):
            raise RuntimeError("Factor is exactly singular")
        return real(A, **kw)

    monkeypatch.setattr(spla, "splu", splu)
    local._lu = None
    z2 = local(r, geo, 3.7e-5)
    assert len(calls) == 2 and calls[1] == {}
    assert np.abs(z2 - z_dense).max() <= 1e-8 * np.abs(z_dense).max()


def test_run_records_the_solve_cost(tmp_path):
    """stokes_solves counts the warm-start product plus one per CG iteration; a local-preconditioned run also
    records its factorisations and the time spent in the preconditioner, a compliance run does not."""
    m = Mm.make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    out = {}
    for pre in ("compliance", "local"):
        cfg = _run_cfg(cg_precond=pre, stretch=0.1, t_end=0.05)
        with xr.open_dataset(run(m, cfg, tmp_path / pre, progress=False)) as ds:
            out[pre] = dict(ds.attrs)
    for attrs in out.values():
        assert attrs["stokes_solves"] == attrs["steps"] + round(attrs["cg_iterations_mean"] * attrs["steps"])
    assert "cg_precond_s" not in out["compliance"]
    assert out["local"]["cg_precond_factorisations"] >= 1 and out["local"]["cg_precond_s"] > 0


def test_smallest_eigenvalue_lanczos_and_its_safe_bound(monkeypatch):
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from vesicle_core.solver.tension import smallest_eigenvalue

    rng = np.random.default_rng(3)
    n = 800
    B = sp.random(n, n, density=0.01, random_state=rng)
    A = (B + B.T + sp.diags(rng.uniform(0.5, 1.0, n))).tocsr()
    exact = np.linalg.eigvalsh(A.toarray())[0]
    assert abs(smallest_eigenvalue(A) - exact) <= 1e-3 * np.abs(np.linalg.eigvalsh(A.toarray())).max()

    def no_convergence(*a, **k):
        raise spla.ArpackNoConvergence("no", np.array([]), np.array([]))

    monkeypatch.setattr(spla, "eigsh", no_convergence)
    assert smallest_eigenvalue(A) <= exact  # Gershgorin: a lower bound, so the shift errs on the safe side


@pytest.mark.slow  # a dense eigenvalue study of the 642-vertex local mobility (pytest -m slow; CI runs it)
def test_local_preconditioner_shifts_an_indefinite_local_mobility():
    """With edges ~ h (642 vertices at N = 32) the truncated pair mobility within 3h is indefinite; the build shifts
    it so P is positive definite, and the CG then reaches the compliance-preconditioned solution."""
    X, F, geo, mob, topo, local, M_loc = _local_case(642)
    lam = np.linalg.eigvalsh(M_loc.toarray())[0]
    assert lam < 0  # the premise: truncation made it indefinite
    dt = 3.7e-5
    local(np.ones(geo.area.shape[0]), geo, dt)
    assert local.shift == pytest.approx(local.margin * local.table.self_mobility - lam, rel=1e-5)
    assert np.linalg.eigvalsh(_assembled_P(M_loc, geo, topo, dt, local.shift))[0] > 0
    u_inf = 268.0 * np.c_[-X[:, 0], X[:, 1], 0 * X[:, 2]]
    zero = np.zeros(geo.area.shape[0])
    out = []
    for pre in (None, local):
        ts = TensionSolver(mob, topo, geo.area.copy(), 1.34e7, tol=1e-10, maxiter=2000, local=pre)
        out.append(ts.solve(geo, F, u_inf, zero, dt, zero)[0])
        assert getattr(ts, "fallbacks", 0) == 0
    assert np.abs(out[1] - out[0]).max() <= 1e-3 * np.abs(out[0]).max()
