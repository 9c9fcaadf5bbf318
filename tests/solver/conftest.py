"""Fixtures shared by the solver tests."""

import pytest
from unit_run import unit_run

from vesicle_core.geometry import mesh as Mm
from vesicle_core.solver.mobility import IBMMobility, IBMSolver
from vesicle_core.solver.tension_harmonic import HarmonicSpace


def _harmonic_setup(n_vertices=162, N=16, l_t=4):
    """A 1:0.8:1 quasi-uniform vesicle at chi = 50 with its forces, prepared mobility and harmonic space:
    (mesh, solver, X, F, geometry, mobility, space)."""
    m = Mm.make_vesicle("quasiuniform", n_vertices=n_vertices, axes=(1.0, 0.8, 1.0))
    s = IBMSolver(m.faces, m.vertices, unit_run(chi=50.0, N=N, scheme="inextensible", tension_space="harmonic"))
    X = s.xp.asarray(m.vertices)
    F, geo = s.forces(X)
    mob = IBMMobility(s.coupler, s.stokes)
    mob.prepare(X)
    return m, s, X, F, geo, mob, HarmonicSpace(m.vertices, m.faces, geo.area.copy(), l_t)


@pytest.fixture(scope="module")
def setup():
    """162 vertices, 16^3, l_t = 4 (see _harmonic_setup)."""
    return _harmonic_setup()


@pytest.fixture
def harmonic_setup():
    """The builder itself, for other sizes: harmonic_setup(n_vertices, N, l_t)."""
    return _harmonic_setup
