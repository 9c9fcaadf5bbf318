"""Orientation order of the wrinkle crests: the structure tensor of the height field at a few scales, its
coherence (the angular anisotropy of the local power spectrum), the crests' topological defects with their
charges, and a global crest-alignment order about the best axis.

Structure tensor at scale sigma
-------------------------------
J_sigma = G_sigma * (grad h grad h^T), smoothed with :class:`~.surface_calculus.HeatSmoother` as a 3x3 ambient
tensor and restricted to each vertex's tangent plane. By Parseval, inside the window the tensor is the second
angular moment of the local power spectrum P_sigma(k), weighted by k^2:
J_sigma = int k k^T P_sigma(k) d^2k. Its eigenvalues lambda_1 >= lambda_2 give the **coherence**::

    c = (lambda_1 - lambda_2) / (lambda_1 + lambda_2) = |int k^2 exp(2 i alpha) P_sigma| / int k^2 P_sigma

(alpha the wave vector's angle): 1 for parallel crests, 0 for a locally isotropic pattern (hexagons, spots, noise)
or for a window containing crests of all orientations (a labyrinth seen at scales beyond its persistence length).
The power-weighted mean of c over the surface is the *angular anisotropy of the local power spectrum*
a_2(sigma); its decay with sigma measures how far the crests keep their orientation.

Crest defects: the crest direction is the eigenvector of lambda_2 (perpendicular to the dominant gradient). Its
index per triangle (:func:`~.surface_calculus.line_field_index`) is a multiple of 1/2; the ends and branch points
of crests are the +1/2 and -1/2 defects, the centre of a bull's eye +1. Their total is chi = 2 on a closed vesicle.

Global crest alignment: T = sum_f A_f t_f t_f^T |grad h|^2 / sum_f A_f |grad h|^2 with t = N x grad h / |grad h|
the crest tangent. If the crests run along the latitudes about an axis a (ripples around a), t . a = 0
everywhere; for isotropic crests T = (I - <N N^T>) / 2, ~ I / 3 on a sphere. The order **P = 1 - 3 lambda_min(T)**
is 1 for ripples about any axis, ~0 for a labyrinth or hexagons, and cos(2 alpha) for a herringbone whose crests
zigzag at +-alpha about the latitudes (tests/analysis/test_crest_order.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..geometry.surface import _as_mesh, cross_rows, face_area_vectors
from .surface_calculus import (
    HeatSmoother,
    edge_angles,
    face_gradients,
    line_field_index,
    tangent_frames,
    vertex_areas,
)

__all__ = ["CrestOrder", "structure_tensor", "crest_order", "crest_alignment"]


@dataclass
class CrestOrder:
    """Crest orientation at one smoothing scale ``sigma`` (units of the vertices).

    coherence (V,); director (V,) crest angle in the vertex frames of :func:`tangent_frames`; anisotropy:
    power-weighted mean coherence a_2; charge (F,) defect index per triangle; n_defects: triangles with a
    nonzero index; total_charge: their sum (2 on a closed genus-0 surface); defect_density: |charge| summed per
    wavelength^2 when ``wavelength`` was given (else per unit area)."""

    sigma: float
    coherence: np.ndarray
    director: np.ndarray
    anisotropy: float
    charge: np.ndarray
    n_defects: int
    total_charge: float
    defect_density: float


def _vertex_tensor(v, f, g):
    """Area-weighted mean of g g^T over the triangles around each vertex, (V, 6) as xx, yy, zz, xy, xz, yz."""
    a = np.linalg.norm(face_area_vectors(v, f), axis=1)
    comps = np.stack([g[:, 0] ** 2, g[:, 1] ** 2, g[:, 2] ** 2, g[:, 0] * g[:, 1], g[:, 0] * g[:, 2],
                      g[:, 1] * g[:, 2]], axis=1) * a[:, None]
    out = np.zeros((len(v), 6))
    for k in range(3):
        for c in range(6):
            out[:, c] += np.bincount(f[:, k], weights=comps[:, c], minlength=len(v))
    return out / np.maximum(3.0 * vertex_areas(v, f), 1e-300)[:, None]


def _tangent_2x2(J6, frames):
    """Components (Jxx, Jyy, Jxy) of the ambient tensors in each vertex's tangent frame (e1, e2)."""
    _, e1, e2 = frames

    def q(a, b):
        xx, yy, zz, xy, xz, yz = J6.T
        return (a[:, 0] * b[:, 0] * xx + a[:, 1] * b[:, 1] * yy + a[:, 2] * b[:, 2] * zz
                + (a[:, 0] * b[:, 1] + a[:, 1] * b[:, 0]) * xy + (a[:, 0] * b[:, 2] + a[:, 2] * b[:, 0]) * xz
                + (a[:, 1] * b[:, 2] + a[:, 2] * b[:, 1]) * yz)

    return q(e1, e1), q(e2, e2), q(e1, e2)


def structure_tensor(vertices, faces, values, sigma, *, frames=None, smoother=None):
    """Tangent structure tensor (Jxx, Jyy, Jxy), each (V,), of the vertex field ``values`` smoothed at ``sigma``."""
    v, f = _as_mesh(vertices, faces)
    frames = tangent_frames(v, f) if frames is None else frames
    smoother = HeatSmoother(v, f, sigma) if smoother is None else smoother
    J6 = smoother(_vertex_tensor(v, f, face_gradients(v, f, values)))
    return _tangent_2x2(J6, frames)


def crest_order(vertices, faces, values, sigma, *, wavelength=None, frames=None, geometry=None,
                smoother=None) -> CrestOrder:
    """Coherence, crest director, anisotropy a_2 and crest defects of the field ``values`` (V,) at scale
    ``sigma``; ``frames`` / ``geometry`` / ``smoother`` may be passed to reuse them across fields."""
    v, f = _as_mesh(vertices, faces)
    frames = tangent_frames(v, f) if frames is None else frames
    geometry = edge_angles(v, f, frames) if geometry is None else geometry
    jxx, jyy, jxy = structure_tensor(v, f, values, sigma, frames=frames, smoother=smoother)
    trace = jxx + jyy
    aniso = np.hypot(jxx - jyy, 2.0 * jxy)
    coherence = aniso / np.maximum(trace, 1e-300)
    director = 0.5 * np.arctan2(2.0 * jxy, jxx - jyy) + 0.5 * np.pi  # crests run across the dominant gradient
    charge = line_field_index(v, f, director, geometry=geometry)
    m = vertex_areas(v, f)
    area = m.sum()
    unit = 1.0 if wavelength is None else float(wavelength) ** 2
    return CrestOrder(
        sigma=float(sigma), coherence=coherence, director=director,
        anisotropy=float((m * aniso).sum() / max((m * trace).sum(), 1e-300)),
        charge=charge, n_defects=int(np.count_nonzero(charge)), total_charge=float(charge.sum()),
        defect_density=float(np.abs(charge).sum() * unit / area),
    )


def crest_alignment(vertices, faces, values, axis=None):
    """Global crest alignment (P, axis): P = 1 - 3 t^T T t with T the crest-tangent tensor of the module
    docstring and t = ``axis`` (unit 3-vector) or, by default, the eigenvector of T's smallest eigenvalue (the axis
    the crests wind around best). Returns (P, axis (3,))."""
    v, f = _as_mesh(vertices, faces)
    g = face_gradients(v, f, values)
    av = face_area_vectors(v, f)
    area = np.linalg.norm(av, axis=1)
    t = cross_rows(av / area[:, None], g)  # |t| = |grad h|: weighting by |grad h|^2 comes with t t^T
    T = (t * area[:, None]).T @ t
    tr = np.trace(T)
    if tr <= 0:
        raise ConfigError("values are constant: the crest alignment needs a field that varies")
    T /= tr
    if axis is None:
        lam, vec = np.linalg.eigh(T)
        return float(1.0 - 3.0 * lam[0]), vec[:, 0]
    a = np.asarray(axis, float).reshape(3)
    a = a / np.linalg.norm(a)
    return float(1.0 - 3.0 * a @ T @ a), a

