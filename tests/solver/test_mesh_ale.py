"""The mesh ALEs' least squares (vesicle_core/solver/mesh_ale.py): its exact minimiser, and a displacement that is a
Lipschitz function of the step's data (what lets two array backends run the ALE to round-off agreement,
tests/solver/test_strict_gpu_path.py). The ALEs' physics (areas held, angles kept, bounded speed, the lipid carried)
is tested in test_tension_harmonic.py."""

import numpy as np
import pytest

from vesicle_core.geometry import mesh as Mm
from vesicle_core.solver import membrane as B
from vesicle_core.solver.mesh_ale import AreaALE, QualityALE, ShapeALE, damped_least_squares, elimination_order
from vesicle_core.solver.tension_harmonic import HarmonicSpace


def test_damped_least_squares_is_the_minimiser():
    """On a rank-deficient matrix (a zero column and two equal ones) the result is the dense solution of the damped
    problem, [A; damp I] u = [b; 0] by an SVD least squares, to the normal equations' round-off, eps (sigma_max /
    damp)^2 ~ 1e-10 relative at the ALE's scales (sigma_max ~ 1 here, 0.4-0.7 in the ALE)."""
    rng = np.random.default_rng(0)
    A = 0.1 * rng.standard_normal((40, 30))
    A[:, 3] = 0.0
    A[:, 7] = A[:, 8]
    b = rng.standard_normal(40)
    damp = 1e-3
    u = damped_least_squares(A, b, damp)
    ref = np.linalg.lstsq(np.vstack([A, damp * np.eye(30)]), np.concatenate([b, np.zeros(30)]), rcond=None)[0]
    np.testing.assert_allclose(u, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    assert u[3] == 0.0 and u[7] == pytest.approx(u[8], rel=1e-9)  # the minimum-norm choice among the minimisers
    # in a given elimination order (the ALE's, from its faces): the same minimiser
    order = np.random.default_rng(1).permutation(30)
    np.testing.assert_allclose(damped_least_squares(A, b, damp, order), u, rtol=0, atol=1e-9 * np.abs(ref).max())


def test_elimination_order_is_a_fill_reducing_permutation():
    """The ALE's order of its 2V unknowns, from the faces: a permutation, the same on every call, that keeps the
    factors of the normal equations sparse (at 642 vertices: within 1.5x of SuperLU's own minimum degree on the
    matrix, and < 1/5 of the dense triangle)."""
    import scipy.sparse as sps
    import scipy.sparse.linalg as spla

    space, m, X, geo, topo, dX, err = _sheared_case()
    order = elimination_order(m.faces, m.n_vertices)
    assert sorted(order) == list(range(2 * m.n_vertices))
    np.testing.assert_array_equal(elimination_order(m.faces, m.n_vertices), order)
    from vesicle_core.solver.mesh_ale import tangent_basis
    from vesicle_core.solver.tension import face_D_matrix

    A = face_D_matrix(geo, topo) @ tangent_basis(X, m.faces)
    normal = (A.T @ A + 1e-6 * sps.identity(A.shape[1])).tocsc()
    opts = {"diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}}
    own = spla.splu(normal, permc_spec="MMD_AT_PLUS_A", **opts)
    ours = spla.splu(normal[order][:, order].tocsc(), permc_spec="NATURAL", **opts)
    n = normal.shape[0]
    assert ours.L.nnz < 1.5 * own.L.nnz and ours.L.nnz < 0.2 * n * (n + 1) / 2


def _sheared_case():
    """A 642-vertex 1:0.8:1 mesh sheared by a differential rotation about z (the quality ALE's angle rows come on for
    some triangles) and an elongational step: (space, reference mesh, X, geometry, topology, dX, area error)."""
    m = Mm.make_vesicle("quasiuniform", n_vertices=642, axes=(1.0, 0.8, 1.0))
    topo = B.Topology(m.faces, m.n_vertices)
    A0 = B.geometry(m.vertices, topo).area
    space = HarmonicSpace(m.vertices, m.faces, A0, 4)
    X = m.vertices + 0.25 * m.vertices[:, 2:3] * np.cross([0.0, 0.0, 1.0], m.vertices)
    dX = 1e-3 * np.stack([X[:, 0], -X[:, 1], np.zeros(len(X))], axis=1)
    geo = B.geometry(X, topo)
    return space, m, X, geo, topo, dX, geo.area - A0


@pytest.mark.parametrize("kind", ["area", "shape", "quality"])
def test_ale_displacement_is_a_lipschitz_function_of_the_positions(kind):
    """Moving the vertices by 1e-12 moves the ALE's displacement by < 1e-9 (measured: 2e-13, 5e-14, 2e-13 for area,
    shape, quality). The displacement of 100 LSQR iterations, which this replaced, moved by 1e-8, 6e-8 and 2e-7:
    an iterate short of the minimiser of a problem with a cluster of near-null singular values amplified round-off
    ~1e4-1e5 times here, ~1e10 in the strict GPU-path test's steps."""
    space, m, X, geo, topo, dX, err = _sheared_case()

    def make():
        return {"area": lambda: AreaALE(space, 0.05),
                "shape": lambda: ShapeALE(space, 0.05, m.vertices, m.faces),
                "quality": lambda: QualityALE(space, 0.05, m.vertices, m.faces)}[kind]()

    ale = make()
    w0 = np.asarray(ale(X, geo, topo, dX, err))
    if kind == "quality":
        assert ale.active > 0  # the angle rows are on, with the ramp between 0 and 1 on some of them
    assert np.abs(w0).max() > 1e-3  # the mesh does move
    Xp = X + 1e-12 * np.random.default_rng(5).standard_normal(X.shape)
    w1 = np.asarray(make()(Xp, B.geometry(Xp, topo), topo, dX, err))
    assert np.abs(w1 - w0).max() < 1e-9
