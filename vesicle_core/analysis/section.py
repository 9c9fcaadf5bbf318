"""The exact section of a triangulated membrane by a plane: what an ideal microscope focused on that plane sees.

The experiment (Kantsler et al. 2007, the paper's Fig. 6) images the vesicle in the flow's plane: the flow
u = chi (x, -y, 0) (eq. 2 reversed) has its plane of extension and compression at z = 0, so the default plane is
z = 0 with normal e_z. Any offset along the normal and any normal are allowed (a focus above the equator, or a
meridional section).

Every triangle of a closed surface that the plane cuts contributes one straight segment (the membrane is piecewise
planar), so the section is exact for the mesh: a set of closed polygons whose vertices lie on the cut edges. The
polygons are ordered and oriented counter-clockwise seen from the side the normal points to (right-handed about the
normal). A vertex lying exactly on the plane is counted on the positive side (symbolic perturbation), which keeps
every cut triangle cut by exactly two edges; the zero-length segments this creates are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, MeshError
from ..geometry.surface import cross_rows

__all__ = ["Plane", "Contour", "plane", "section", "main_section"]


@dataclass(frozen=True)
class Plane:
    """The plane {x : (x - origin) . normal = 0} with an in-plane orthonormal basis (e1, e2), e1 x e2 = normal."""

    origin: np.ndarray
    normal: np.ndarray
    e1: np.ndarray
    e2: np.ndarray

    def to_plane(self, points) -> np.ndarray:
        """In-plane coordinates (N, 2) of points (N, 3)."""
        rel = np.asarray(points, float) - self.origin
        return np.stack([rel @ self.e1, rel @ self.e2], axis=1)

    def to_space(self, uv) -> np.ndarray:
        """Points (N, 3) of in-plane coordinates (N, 2)."""
        uv = np.asarray(uv, float)
        return self.origin + uv[:, :1] * self.e1 + uv[:, 1:2] * self.e2


def plane(normal=(0.0, 0.0, 1.0), offset: float = 0.0, center=(0.0, 0.0, 0.0)) -> Plane:
    """The plane of unit ``normal`` at signed distance ``offset`` from ``center`` along it.

    e1 is the lab axis (x, then y) least parallel to the normal, projected on the plane: for the default plane
    z = 0, (e1, e2) = (e_x, e_y), the flow's extension and compression axes."""
    n = np.asarray(normal, float).reshape(3)
    norm = np.linalg.norm(n)
    if not np.isfinite(norm) or norm == 0:
        raise ConfigError(f"plane normal must be a finite non-zero 3-vector, got {tuple(n)}")
    n = n / norm
    if not np.isfinite(offset):
        raise ConfigError(f"plane offset must be finite, got {offset}")
    axis = np.eye(3)[0] if abs(n[0]) < 0.9 else np.eye(3)[1]
    e1 = axis - (axis @ n) * n
    e1 /= np.linalg.norm(e1)
    e2 = cross_rows(n[None], e1[None])[0]
    origin = np.asarray(center, float).reshape(3) + float(offset) * n
    return Plane(origin, n, e1, e2)


@dataclass(frozen=True)
class Contour:
    """One closed polygon of a section: ``points`` (n, 3) in space, ``uv`` (n, 2) in the plane's basis, counter-
    clockwise about the normal; ``faces`` (n,) the triangle holding the segment from point i to point i + 1."""

    points: np.ndarray
    uv: np.ndarray
    faces: np.ndarray

    @property
    def n(self) -> int:
        return int(len(self.uv))

    def length(self) -> float:
        return float(np.linalg.norm(np.roll(self.uv, -1, axis=0) - self.uv, axis=1).sum())

    def area(self) -> float:
        """Signed enclosed area (shoelace): positive for a counter-clockwise polygon."""
        u, v = self.uv.T
        return float(0.5 * np.sum(u * np.roll(v, -1) - np.roll(u, -1) * v))

    def centroid(self) -> np.ndarray:
        """Area centroid (2,) in the plane's basis."""
        u, v = self.uv.T
        cr = u * np.roll(v, -1) - np.roll(u, -1) * v
        a = 0.5 * cr.sum()
        return np.array([((u + np.roll(u, -1)) * cr).sum(), ((v + np.roll(v, -1)) * cr).sum()]) / (6.0 * a)


def _cut_faces(faces, side):
    """The faces the plane cuts, the edge id of each one's three edges (n, 3; edge k of a face is (v_k, v_k+1)) and
    the edges' end points (E, 2). Only the cut faces are looked at: O(sqrt(F)) of them on a closed surface."""
    f = np.asarray(faces)
    n_pos = side[f].sum(axis=1)
    idx = np.flatnonzero((n_pos == 1) | (n_pos == 2))
    fc = f[idx].astype(np.int64)
    directed = np.stack([fc[:, [0, 1]], fc[:, [1, 2]], fc[:, [2, 0]]], axis=1)
    lo, hi = directed.min(axis=2), directed.max(axis=2)
    n = np.int64(len(side))
    keys, inverse = np.unique((lo * n + hi).ravel(), return_inverse=True)
    return idx, inverse.reshape(-1, 3), np.stack([keys // n, keys % n], axis=1)


def _segments(faces, side, idx, face_edges):
    """For each cut face, the (from, to) cut-edge ids of its segment, oriented counter-clockwise about the normal.

    In a triangle (v0, v1, v2), counter-clockwise seen from outside, let v_i be the vertex alone on its side. The
    cut edges are (v_{i-1}, v_i) and (v_i, v_{i+1}); with v_i above the plane the outward normal turns the path
    from the first to the second clockwise about the plane's normal, so the segment runs from the second to the
    first (and the other way with v_i below)."""
    s = side[np.asarray(faces)[idx]]
    lone_pos = s.sum(axis=1) == 1
    lone = np.where(lone_pos, np.argmax(s, axis=1), np.argmin(s, axis=1))
    rows = np.arange(len(idx))
    before = face_edges[rows, (lone + 2) % 3]  # edge (v_{i-1}, v_i)
    after = face_edges[rows, lone]  # edge (v_i, v_{i+1})
    start = np.where(lone_pos, after, before)
    stop = np.where(lone_pos, before, after)
    return start, stop


def _chain(start, stop, n_edges):
    """Closed loops of the successor map start -> stop: a list of index arrays into the segments."""
    seg_of = np.full(n_edges, -1)
    seg_of[start] = np.arange(len(start))
    if np.any(seg_of[stop] < 0) or len(np.unique(start)) != len(start):
        raise MeshError("the section is not a set of closed curves: the mesh is not closed or not consistently "
                        "oriented")
    seen = np.zeros(len(start), bool)
    loops = []
    for s0 in range(len(start)):
        if seen[s0]:
            continue
        loop = []
        s = s0
        while not seen[s]:
            seen[s] = True
            loop.append(s)
            s = seg_of[stop[s]]
        loops.append(np.asarray(loop))
    return loops


def section(vertices, faces, where: Plane | None = None, *, min_points: int = 3) -> list[Contour]:
    """The exact section of the closed, outward-oriented triangulated surface (vertices, faces) by ``where``
    (default: z = 0, the flow's plane): a list of closed contours, the longest first (empty if the plane misses)."""
    v = np.asarray(vertices, float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise MeshError(f"section needs vertices (V, 3) and faces (F, 3), got {v.shape} and {f.shape}")
    where = plane() if where is None else where
    d = (v - where.origin) @ where.normal
    side = d >= 0.0
    idx, face_edges, edges = _cut_faces(f, side)
    if not len(idx):
        return []
    a, b = edges[:, 0], edges[:, 1]
    cut = side[a] != side[b]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(cut, d[a] / np.where(cut, d[a] - d[b], 1.0), 0.0)
    pts = v[a] + t[:, None] * (v[b] - v[a])
    start, stop = _segments(f, side, idx, face_edges)
    scale = float(np.ptp(v, axis=0).max()) or 1.0
    out = []
    for loop in _chain(start, stop, len(edges)):
        p = pts[start[loop]]
        keep = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1) > 1e-13 * scale
        if keep.sum() < min_points:
            continue
        p = p[keep]
        out.append(Contour(p, where.to_plane(p), idx[loop][keep]))
    return sorted(out, key=lambda c: -c.length())


def main_section(vertices, faces, where: Plane | None = None) -> Contour:
    """The longest contour of the section (the vesicle's outline in the focal plane); MeshError if none."""
    cs = section(vertices, faces, where)
    if not cs:
        raise MeshError("the plane does not cut the membrane")
    return cs[0]
