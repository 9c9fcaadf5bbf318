"""Mesh bias: how strongly a wrinkle pattern follows the mesh (the icosphere's twelve five-fold defects and the
icosahedral degrees l = 6, 10, 12) rather than the membrane; docs/explanation/mesh_bias.md.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.surface import _as_mesh
from .shape import wrinkle_amplitude

ICOSAHEDRAL_DEGREES = (6, 10, 12)


NON_ICOSAHEDRAL_DEGREES = (8, 14)


def icosahedron_directions() -> np.ndarray:
    """Unit vectors to the 12 vertices of the icosahedron from which ``mesh.icosphere`` is subdivided
    (its five-fold vertices; in an ellipsoid mapped from it they keep indices 0..11)."""
    from ..geometry.mesh import icosphere

    return icosphere(0)[0]


def vertex_valence(faces, n_vertices) -> np.ndarray:
    f = np.asarray(faces)
    return np.bincount(f.ravel(), minlength=n_vertices)  # closed triangle mesh: faces per vertex = valence


def mesh_bias(vertices, faces, ellipsoid, Delta_tilde_l=None) -> dict:
    """How strongly the wrinkle pattern follows the mesh rather than the membrane.

    * ``defect_amplitude_ratio``: rms wrinkle amplitude A_p at the mesh's topological defects (vertices of
      valence != 6) over its rms at all vertices. ~1 when wrinkles ignore the defects; >> 1 when they pin to
      them (the icosphere's 12 five-fold vertices).
    * ``icosahedral_amplitude_ratio``: the same at the vertices nearest to the 12 icosahedron directions
      (measured the same way on any mesh family, so it is a control for non-icosphere meshes).
    * ``icosahedral_power_ratio``: mean Delta~_l over l = 6, 10, 12 (the degrees that carry icosahedrally
      invariant harmonics) over the mean at the even degrees 8, 14 that carry none; ~1 for a smooth
      unbiased spectrum. Needs ``Delta_tilde_l`` (indexed by l) reaching l = 14, else NaN.
    """
    v, f = _as_mesh(vertices, faces)
    ap = wrinkle_amplitude(v, f, ellipsoid, at="vertices")
    rms = math.sqrt(float(np.mean(ap**2)))
    val = vertex_valence(f, len(v))
    defects = val != 6
    c = v - v.mean(axis=0)
    dirs = c / np.linalg.norm(c, axis=1, keepdims=True)
    ico = np.unique(np.argmax(dirs @ icosahedron_directions().T, axis=0))
    out = {
        "defect_amplitude_ratio": (math.sqrt(float(np.mean(ap[defects] ** 2))) / rms
                                   if defects.any() and rms > 0 else math.nan),
        "icosahedral_amplitude_ratio": math.sqrt(float(np.mean(ap[ico] ** 2))) / rms if rms > 0 else math.nan,
        "n_defects": int(defects.sum()),
        "icosahedral_power_ratio": math.nan,
    }
    if Delta_tilde_l is not None and len(Delta_tilde_l) > max(NON_ICOSAHEDRAL_DEGREES):
        D = np.asarray(Delta_tilde_l, dtype=float)
        den = D[list(NON_ICOSAHEDRAL_DEGREES)].mean()
        out["icosahedral_power_ratio"] = float(D[list(ICOSAHEDRAL_DEGREES)].mean() / den) if den > 0 else math.nan
    return out
