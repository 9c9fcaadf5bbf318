"""Calculus of fields on a triangulated membrane for the morphology metrics: gradients of a piecewise-linear field,
a heat-kernel smoothing, tangent frames with their discrete Levi-Civita connection, and the index of a line field.

Gradient: h linear on each triangle has the constant tangent gradient grad h = sum_i h_i (N x e_i) / (2 A), e_i the
edge opposite vertex i taken counter-clockwise, N the unit normal, A the area.

Smoothing at scale sigma: one backward-Euler step of the heat equation, (M + t L) x = M x_0 with t = sigma^2 / 2
(M lumped vertex areas, L the cotangent Laplacian). Its kernel has the variance 2 t = sigma^2 of a Gaussian of
width sigma (it is the resolvent, a Bessel-K0-like kernel, not a Gaussian).

Line fields and their defects (Knoeppel et al. 2013, "Globally optimal direction fields", Sec. 4; Ray et al. 2008)
--------------------------------------------------------------------------------------------------------
Every vertex i gets a tangent frame (e1, e2, n_i) with n_i the vertex normal. phi_ij is the polar angle, in frame i,
of the edge i -> j projected on the tangent plane. Carrying a vector along the edge from i to j turns its angle by
rho_ij = phi_ji + pi - phi_ij (the edge keeps its angle to the vector), so rho_ji = 2 pi - rho_ij. The curvature of
triangle (a, b, c), counter-clockwise, is its angle excess in these projected angles,
kappa_f = sum_corners mod_2pi(phi_ac - phi_ab) - pi, and sum_f kappa_f = 2 pi V - pi F = 2 pi chi exactly when
every vertex's star projects without folds (discrete Gauss-Bonnet).

A line field (a direction defined up to sign, the crests' orientation) is an angle psi_i per vertex, taken mod pi.
Around triangle f its turning relative to the transported frame is
delta_ab = wrap_pi(2 (psi_b - psi_a - rho_ab)) / 2 per edge (the shortest turn of a headless direction), and the
index of the field in f is ``(sum_edges delta + kappa_f) / (2 pi)``: a multiple of 1/2 (half-integers are the
nematic defects). The deltas cancel between the two triangles of every edge, so the indices sum to
chi = 2 on a closed genus-0 surface whatever the field (Poincare-Hopf for line fields); on a torus they sum to 0.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..errors import ConfigError
from ..geometry.surface import _as_mesh, cross_rows, dot_rows, face_area_vectors, vertex_normals

__all__ = ["face_gradients", "vertex_areas", "cotan_laplacian", "HeatSmoother", "tangent_frames",
           "edge_angles", "line_field_index", "unit_rows"]


def unit_rows(a):
    return a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-300)


def face_gradients(vertices, faces, values) -> np.ndarray:
    """Tangent gradient (F, 3) of the field linear on each triangle with vertex ``values`` (V,)."""
    v, f = _as_mesh(vertices, faces)
    h = np.asarray(values, float)
    if h.shape != (len(v),):
        raise ConfigError(f"values must hold one entry per vertex ({len(v)}), got shape {h.shape}")
    av = face_area_vectors(v, f)
    two_a = 2.0 * np.linalg.norm(av, axis=1)
    n = av / two_a[:, None] * 2.0
    g = np.zeros((len(f), 3))
    for k in range(3):
        e = v[f[:, (k + 2) % 3]] - v[f[:, (k + 1) % 3]]
        g += h[f[:, k], None] * cross_rows(n, e)
    return g / two_a[:, None]


def vertex_areas(vertices, faces) -> np.ndarray:
    """Lumped (barycentric) vertex areas: a third of each adjacent triangle, (V,)."""
    v, f = _as_mesh(vertices, faces)
    a = np.linalg.norm(face_area_vectors(v, f), axis=1)
    return np.bincount(f.ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(v))


def cotan_laplacian(vertices, faces) -> sp.csc_matrix:
    """Positive semi-definite cotangent Laplacian L (V, V): (L x)_i = sum_j (cot a_ij + cot b_ij)/2 (x_i - x_j)."""
    v, f = _as_mesh(vertices, faces)
    rows, cols, vals = [], [], []
    for k in range(3):
        i, j, o = f[:, (k + 1) % 3], f[:, (k + 2) % 3], f[:, k]
        a, b = v[i] - v[o], v[j] - v[o]
        cot = dot_rows(a, b) / np.maximum(np.linalg.norm(cross_rows(a, b), axis=1), 1e-300)
        rows += [i, j]
        cols += [j, i]
        vals += [-0.5 * cot, -0.5 * cot]
    W = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(len(v),) * 2)
    W = W.tocsc()
    return (sp.diags(-np.asarray(W.sum(axis=1)).ravel()) + W).tocsc()


class HeatSmoother:
    """Smooth vertex fields at length ``sigma`` (units of the vertices): x = (M + sigma^2/2 L)^-1 M x_0, one
    factorisation reused for every field. sigma = 0 returns the field unchanged."""

    def __init__(self, vertices, faces, sigma):
        if not sigma >= 0:
            raise ConfigError(f"sigma must be >= 0, got {sigma}")
        self.sigma = float(sigma)
        self.mass = vertex_areas(vertices, faces)
        self._lu = None
        if self.sigma > 0:
            A = sp.diags(self.mass) + 0.5 * self.sigma**2 * cotan_laplacian(vertices, faces)
            # A is symmetric positive definite (mass plus the P1 stiffness matrix): a symmetric ordering without
            # pivoting factorises it in about half the time of the general LU, with the same solution to rounding
            self._lu = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                            options={"SymmetricMode": True})

    def __call__(self, x):
        x = np.asarray(x, float)
        if self._lu is None:
            return x.copy()
        rhs = self.mass[:, None] * x.reshape(len(self.mass), -1)
        return self._lu.solve(rhs).reshape(x.shape)


def tangent_frames(vertices, faces):
    """(n, e1, e2), each (V, 3): vertex normal and an orthonormal tangent basis (e1 along a projected edge)."""
    v, f = _as_mesh(vertices, faces)
    n = vertex_normals(v, f)
    ref = np.zeros_like(v)
    for k in range(3):
        ref[f[:, k]] = v[f[:, (k + 1) % 3]] - v[f[:, k]]
    e1 = unit_rows(ref - dot_rows(ref, n)[:, None] * n)
    return n, e1, cross_rows(n, e1)


def _angle_in_frame(vec, frame_idx, frames):
    _, e1, e2 = frames
    return np.arctan2(dot_rows(vec, e2[frame_idx]), dot_rows(vec, e1[frame_idx]))


def edge_angles(vertices, faces, frames=None):
    """Per face (F, 3) arrays: rho[:, c] the connection of the directed edge f[c] -> f[c+1]; and the face
    curvature kappa (F,) of the module docstring."""
    v, f = _as_mesh(vertices, faces)
    frames = tangent_frames(v, f) if frames is None else frames
    nxt = np.empty((len(f), 3))
    prv = np.empty((len(f), 3))
    for c in range(3):
        a, b, p = f[:, c], f[:, (c + 1) % 3], f[:, (c + 2) % 3]
        nxt[:, c] = _angle_in_frame(v[b] - v[a], a, frames)
        prv[:, c] = _angle_in_frame(v[p] - v[a], a, frames)
    rho = np.roll(prv, -1, axis=1) + math.pi - nxt  # phi_ba is the "previous" angle at corner c + 1
    corners = np.mod(prv - nxt, 2.0 * math.pi)
    return rho, corners.sum(axis=1) - math.pi


def line_field_index(vertices, faces, psi, *, geometry=None) -> np.ndarray:
    """Index (F,) of the line field with vertex angles ``psi`` (V,) (frame of :func:`tangent_frames`, mod pi) in
    every triangle: multiples of 1/2, summing to the surface's Euler characteristic. ``geometry``: a cached
    (rho, kappa) from :func:`edge_angles` for the same frames."""
    v, f = _as_mesh(vertices, faces)
    rho, kappa = edge_angles(v, f) if geometry is None else geometry
    psi = np.asarray(psi, float)
    turn = np.zeros(len(f))
    for c in range(3):
        d = 2.0 * (psi[f[:, (c + 1) % 3]] - psi[f[:, c]] - rho[:, c])
        turn += 0.5 * (np.mod(d + math.pi, 2.0 * math.pi) - math.pi)
    idx = (turn + kappa) / (2.0 * math.pi)
    return np.round(2.0 * idx) / 2.0
