"""The analysis of one snapshot (analysis.shape.analyze_snapshot, Sec. V: the spherical-harmonic decomposition
u_lm, Delta_l and l_* of eqs. 30-31, the ellipsoid fit and the wrinkle amplitude A_p of eq. 32).

``vesicle decompose`` does this once per stored frame (50 in a default run). l_max is its default, what the mesh
resolves (geometry.surface.resolvable_l_max, capped at 64): the decomposition's cost grows as l_max^2 times the
quadrature nodes. Host float64 only, so not parametrised over the grid's dtype.
"""

import numpy as np

from vesicle_core.analysis.shape import analyze_snapshot
from vesicle_core.analysis.spectra import _choose_l_max

from .common import NS, mesh_for


class SnapshotAnalysis:
    """One frame of the N-matched mesh, wrinkled at random (1% of R), up to its resolvable l_max."""

    params = NS
    param_names = ["N"]
    timeout = 120

    def setup(self, N):
        m = mesh_for(N)
        rng = np.random.default_rng(3)
        r = np.linalg.norm(m.vertices, axis=1, keepdims=True)
        self.X = m.vertices * (1.0 + 0.01 * rng.standard_normal(r.shape))
        self.faces = m.faces
        self.l_max, _ = _choose_l_max(None, m.vertices, m.faces)  # as spectra.decompose chooses it

    def time_analyze_snapshot(self, N):
        analyze_snapshot(self.X, self.faces, self.l_max, warn=False)

    def peakmem_analyze_snapshot(self, N):
        analyze_snapshot(self.X, self.faces, self.l_max, warn=False)

    def track_l_max(self, N):
        return self.l_max

    track_l_max.unit = "l"
