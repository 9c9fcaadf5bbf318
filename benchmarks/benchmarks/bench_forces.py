"""The membrane forces (App. A): bending plus tension, on the N-matched meshes (596 and 2379 vertices).

* ``time_forces``: Membrane.forces, the Helfrich bending force (eq. A2-A4 discretised, eq. 25's energy) plus the
  area penalty (A5) and the volume penalty: the whole force of the explicit and projection schemes;
* ``time_tension_force``: D^T sigma, the force of a given per-triangle tension (the inextensible scheme's unknown;
  tension.face_DT), and ``time_area_rate``: its transpose D U, the triangle area rates of a vertex velocity. The
  tension CG applies both once per iteration, around each Stokes solve.

Positions and forces are float64 whatever the grid's ``dtype``, so these are not parametrised over it.
"""

import numpy as np

from vesicle_core.solver import membrane as B
from vesicle_core.solver.tension import face_D, face_DT

from .common import NS, mesh_for, perturbed


class MembraneForces:
    """Forces on the mesh of grid N (its size: 596 vertices at N = 32, 2379 at N = 64)."""

    params = NS
    param_names = ["N"]

    def setup(self, N):
        m = mesh_for(N)
        self.mem = B.Membrane.from_mesh(m.vertices, m.faces, Lambda=1e6, K_volume=1e7)
        self.X = perturbed(m.vertices)
        _, self.geo = self.mem.forces(self.X)
        rng = np.random.default_rng(2)
        self.sigma = rng.standard_normal(m.faces.shape[0])
        self.U = rng.standard_normal(self.X.shape)

    def time_forces(self, N):
        self.mem.forces(self.X)

    def time_tension_force(self, N):
        face_DT(self.sigma, self.geo, self.mem.topo)

    def time_area_rate(self, N):
        face_D(self.U, self.geo, self.mem.topo)
