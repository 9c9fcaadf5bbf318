"""Surface quantities of a closed triangulated membrane: cross and dot products, face area vectors, triangle
areas, the enclosed volume and its centroid, solid angles, the equivalent radius, the resolvable l, face and vertex
normals, vertex averages and PN patch centres.

The one home of these formulas: the mesh generator, the membrane mechanics, the tension spaces, the spherical-
harmonic analysis and the renders take them from here.

Two layouts meet here. The solver stores vectors component-first, ``(3, ...)`` (each operation is then an
elementwise kernel on contiguous rows, NumPy or CuPy): :func:`cross` and :func:`dot`. Meshes and the analysis store
rows, ``(n, 3)``: :func:`cross_rows` (``cross`` on transposed views, bitwise ``np.cross``) and :func:`dot_rows`
(``np.einsum`` over the rows). The two dot products sum the three components in different orders (einsum pairs
them), so each layout keeps its own, and every result is bit for bit what the code that used to compute it gave.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import MeshError
from ..xp import array_module, to_float


def cross(a, b):
    """a x b over the leading (component) axis: arrays of shape (3, ...), NumPy or CuPy."""
    return array_module(a).stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def dot(a, b):
    """a . b over the leading (component) axis: arrays of shape (3, ...) -> (...), summed left to right."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def dot_rows(a, b):
    """Row-wise a . b of (n, 3) arrays -> (n,) (NumPy)."""
    return np.einsum("ij,ij->i", a, b)


def cross_rows(a, b):
    """np.cross of (n, 3) rows, as a contiguous (n, 3) array."""
    return np.ascontiguousarray(cross(a.T, b.T).T)


def face_area_vectors(vertices, faces):
    """Half cross products 0.5 (x_j - x_i) x (x_k - x_i), (F, 3): |a| is the area, a/|a| the outward normal."""
    xi, xj, xk = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    return 0.5 * cross_rows(xj - xi, xk - xi)


def face_normals(vertices, faces):
    """Unit outward normal of every triangle, (F, 3)."""
    a = face_area_vectors(vertices, faces)
    return a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-300)


def surface_area(vertices, faces) -> float:
    return float(np.linalg.norm(face_area_vectors(vertices, faces), axis=1).sum())


def _tet_volumes(a, b, c):
    """Signed volumes a . (b x c) / 6 of the tetrahedra (0, a, b, c), rows (F, 3) -> (F,)."""
    return dot_rows(a, cross_rows(b, c)) / 6.0


def enclosed_volume(vertices, faces) -> float:
    """Signed volume (divergence theorem); positive for outward-oriented closed surfaces."""
    xi, xj, xk = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    return float(dot_rows(xi, cross_rows(xj, xk)).sum() / 6.0)


def corner_volume(P0, P1, P2) -> float:
    """Enclosed volume from the three corners of every triangle, each component-first (3, F) (the solver's
    layout): the same divergence-theorem sum as :func:`enclosed_volume`."""
    return to_float(dot(P0, cross(P1, P2)).sum() / 6.0)


def vertex_average(vertices, faces, face_values) -> np.ndarray:
    """Area-weighted mean of the face values around each vertex, (V,)."""
    area = np.linalg.norm(face_area_vectors(vertices, faces), axis=1)
    num = np.bincount(faces.ravel(), weights=np.repeat(face_values * area, 3), minlength=len(vertices))
    den = np.bincount(faces.ravel(), weights=np.repeat(area, 3), minlength=len(vertices))
    return num / np.maximum(den, 1e-300)


def _as_mesh(vertices, faces):
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must have shape (V, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise MeshError(f"faces must have shape (F, 3), got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        raise MeshError(f"faces must hold integer vertex indices, got dtype {f.dtype}")
    if len(f) == 0 or f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"face indices must lie in [0, {len(v) - 1}]")
    if not np.all(np.isfinite(v)):
        raise MeshError("vertices contain NaN or Inf")
    return v, f.astype(np.int64, copy=False)


def triangle_areas(vertices, faces) -> np.ndarray:
    """Area of every triangle, shape (F,)."""
    v, f = _as_mesh(vertices, faces)
    return np.linalg.norm(face_area_vectors(v, f), axis=1)


def triangle_area_nonlinear(vertices, faces, displacement) -> np.ndarray:
    """A(X + dX) - A(X) - (dA/dX) dX for every triangle, shape (F,): the part of a displacement's area change that
    is not linear in it (O(|dX|^2), exactly zero for a rigid translation), in float64 whatever the inputs' dtype."""
    v, f = _as_mesh(vertices, faces)
    d = np.asarray(displacement, dtype=float)
    if d.shape != v.shape:
        raise MeshError(f"displacement must have the vertices' shape {v.shape}, got {d.shape}")
    a = face_area_vectors(v, f)
    area = np.linalg.norm(a, axis=1)
    xi, xj, xk = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    di, dj, dk = d[f[:, 0]], d[f[:, 1]], d[f[:, 2]]
    # the area vector's first-order change; the area's is its component along the normal
    a1 = 0.5 * (cross_rows(dj - di, xk - xi) + cross_rows(xj - xi, dk - di))
    linear = (a * a1).sum(axis=1) / np.maximum(area, 1e-300)
    return np.linalg.norm(face_area_vectors(v + d, f), axis=1) - area - linear


def volume_centroid(vertices, faces) -> np.ndarray:
    """Centroid of the solid enclosed by a closed, outward-oriented surface (sum over tetrahedra to a
    reference point; computed relative to the vertex mean to avoid round-off far from the origin)."""
    v, f = _as_mesh(vertices, faces)
    o = v.mean(axis=0)
    a, b, c = v[f[:, 0]] - o, v[f[:, 1]] - o, v[f[:, 2]] - o
    vol = _tet_volumes(a, b, c)
    V = vol.sum()
    if not V > 0:
        raise MeshError(f"enclosed volume is {V:g}; the surface must be closed with outward normals")
    return o + (vol[:, None] * (a + b + c)).sum(axis=0) / (4.0 * V)


def solid_angles(vertices, faces, center) -> np.ndarray:
    """Signed solid angle each triangle subtends at ``center`` (Van Oosterom & Strackee 1983).

    Positive for triangles seen counter-clockwise from the centre's outside; sums to 4 pi on a closed outward
    surface enclosing ``center``.
    """
    v, f = _as_mesh(vertices, faces)
    c0 = np.asarray(center, dtype=float)
    a, b, c = v[f[:, 0]] - c0, v[f[:, 1]] - c0, v[f[:, 2]] - c0
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    num = dot_rows(a, cross_rows(b, c))
    den = la * lb * lc + dot_rows(a, b) * lc + dot_rows(a, c) * lb + dot_rows(b, c) * la
    return 2.0 * np.arctan2(num, den)


def _equivalent_radius(v, f) -> float:
    vol = enclosed_volume(v, f)
    if not vol > 0:
        raise MeshError(f"enclosed volume is {vol:g}; the surface must be closed with outward normals")
    return (3.0 * vol / (4.0 * math.pi)) ** (1.0 / 3.0)


def resolvable_l_max(vertices, faces, R=None) -> int:
    """Largest l the mesh resolves: floor(pi / h), h the mean edge length in radians (h / R).

    A mode l has wavelength 2 pi R / l; representing it needs at least two edges per wavelength.
    Unit icosphere levels 3 / 4 / 5 / 6 give 41 / 83 / 167 / 334 (mean edge 0.075 / 0.038 / 0.019 / 0.0094 R) --
    note that at level 3 this is about 20.
    """
    v, f = _as_mesh(vertices, faces)
    if R is None:
        R = _equivalent_radius(v, f)
    # on a closed mesh every edge borders exactly two faces, so the mean over face edges is the mean edge
    e = v[f[:, [1, 2, 0]]] - v[f]
    h = np.linalg.norm(e, axis=2).mean() / R
    return int(math.floor(math.pi / h))


def vertex_normals(vertices, faces) -> np.ndarray:
    """Unit vertex normals with Max's (1999) weights (face normal / (|e1|^2 |e2|^2) per incident corner), exact for
    vertices on a sphere; outward for an outward-oriented mesh."""
    v, f = _as_mesh(vertices, faces)
    n = np.zeros_like(v)
    for k in range(3):
        p = v[f[:, k]]
        e1 = v[f[:, (k + 1) % 3]] - p
        e2 = v[f[:, (k + 2) % 3]] - p
        c = cross_rows(e1, e2) / (dot_rows(e1, e1) * dot_rows(e2, e2))[:, None]
        for d in range(3):
            n[:, d] += np.bincount(f[:, k], weights=c[:, d], minlength=len(v))
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    norm[norm == 0] = 1.0
    return n / norm


def pn_centers(vertices, faces, normals=None) -> np.ndarray:
    """Centre (barycentric 1/3, 1/3, 1/3) of the cubic PN triangle (Vlachos et al. 2001) of every face: the
    curved patch through the three vertices, tangent to the vertex normals. It lies on the smooth surface the
    membrane points sample (on a sphere mesh: within O(h^4) of the sphere), not inside it like the flat centroid."""
    v, f = _as_mesh(vertices, faces)
    N = vertex_normals(v, f) if normals is None else np.asarray(normals, float)
    P = [v[f[:, k]] for k in range(3)]
    Nk = [N[f[:, k]] for k in range(3)]

    def b(i, j):  # edge control point near vertex i on edge ij: (2 P_i + P_j - ((P_j - P_i).N_i) N_i) / 3
        w = dot_rows(P[j] - P[i], Nk[i])[:, None]
        return (2.0 * P[i] + P[j] - w * Nk[i]) / 3.0

    edge = b(0, 1) + b(1, 0) + b(1, 2) + b(2, 1) + b(2, 0) + b(0, 2)
    V = (P[0] + P[1] + P[2]) / 3.0
    E = edge / 6.0
    b111 = E + 0.5 * (E - V)
    # Bernstein weights at (1/3, 1/3, 1/3): corners 1/27, edge points 3/27, centre 6/27
    return (P[0] + P[1] + P[2]) / 27.0 + edge / 9.0 + (2.0 / 9.0) * b111
