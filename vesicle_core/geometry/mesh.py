"""Triangulated vesicle surfaces: icosphere and quasi-uniform sphere meshes, mapped onto an
ellipsoid of given axes ratio and scaled to the volume of a sphere of radius R.

The excess area Delta = A / R^2 - 4 pi (Sec. III) is computed from the *meshed* surface: a faceted
ellipsoid carries area of its own (the 1:0.8:1 ellipsoid has Delta = 0.1153 exactly
but 0.166 / 0.128 / 0.118 / 0.116 at icosphere levels 2-5), so every run records the meshed value.

Faces are ordered counter-clockwise seen from outside (outward normals), as App. A requires.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, MeshError, check_range
from .surface import dot_rows, enclosed_volume, face_area_vectors, surface_area

MAX_ICOSPHERE_LEVEL = 9  # level 9: 2.6 M vertices, already far beyond a 512^3 grid (edge ~ h)
FAMILIES = ("icosphere", "quasiuniform")


@dataclass
class Mesh:
    """A closed triangulated surface: vertices (V, 3) float64, faces (F, 3) int64, metadata attrs."""

    vertices: np.ndarray
    faces: np.ndarray
    attrs: dict = field(default_factory=dict)

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    def edges(self) -> np.ndarray:
        return unique_edges(self.faces)

    def area(self) -> float:
        return surface_area(self.vertices, self.faces)

    def volume(self) -> float:
        return enclosed_volume(self.vertices, self.faces)

    def equivalent_radius(self) -> float:
        return (3.0 * self.volume() / (4.0 * math.pi)) ** (1.0 / 3.0)

    def excess_area(self) -> float:
        """Delta = A / R^2 - 4 pi with R the radius of the sphere of equal volume."""
        R = self.equivalent_radius()
        return self.area() / R**2 - 4.0 * math.pi

    def quality(self) -> dict:
        return mesh_quality(self.vertices, self.faces)

    def check(self) -> Mesh:
        check_closed_surface(self.vertices, self.faces)
        return self


# --------------------------------------------------------------------------- geometry helpers

def vertices_for_edge(edge: float, radius: float = 1.0) -> int:
    """Vertex count of a sphere mesh with mean edge ``edge``: equilateral triangles (area sqrt(3)/4 edge^2), two per
    vertex, covering 4 pi radius^2."""
    return int(round(4.0 * math.pi * radius**2 / (math.sqrt(3) / 4 * edge**2) / 2.0 + 2))

def unique_edges(faces) -> np.ndarray:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def check_closed_surface(vertices, faces) -> None:
    """Raise MeshError unless the mesh is a closed, consistently oriented, outward, genus-0 surface."""
    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise MeshError(f"vertices must have shape (V, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise MeshError(f"faces must have shape (F, 3), got {faces.shape}")
    if not np.all(np.isfinite(vertices)):
        raise MeshError("vertices contain NaN or Inf")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError(f"face indices must lie in [0, {len(vertices) - 1}]")
    if np.any((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])):
        raise MeshError("a face repeats a vertex (degenerate triangle)")
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    V = len(vertices)
    key = directed[:, 0] * V + directed[:, 1]
    if len(np.unique(key)) != len(key):
        raise MeshError("an oriented edge appears twice: faces are not consistently oriented or not manifold")
    rev = directed[:, 1] * V + directed[:, 0]
    if not np.all(np.isin(rev, key)):
        raise MeshError("mesh is not closed: some edges have a single adjacent face")
    used = np.zeros(V, bool)
    used[faces.ravel()] = True
    if not used.all():
        raise MeshError(f"{int((~used).sum())} vertices belong to no face")
    E = len(key) // 2
    chi = V - E + len(faces)
    if chi != 2:
        raise MeshError(f"mesh is not genus 0: V - E + F = {chi}, expected 2")
    if enclosed_volume(vertices, faces) <= 0:
        raise MeshError("faces are oriented inward (negative enclosed volume); expected outward normals")


def mesh_quality(vertices, faces) -> dict:
    """Edge lengths (min/mean/max, spread = std/mean), triangle aspect ratios and angles.

    Aspect ratio: longest edge over (2 sqrt(3) x inradius); 1 for an equilateral triangle.
    """
    e = unique_edges(faces)
    L = np.linalg.norm(vertices[e[:, 1]] - vertices[e[:, 0]], axis=1)
    xi, xj, xk = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    a = np.linalg.norm(xk - xj, axis=1)
    b = np.linalg.norm(xi - xk, axis=1)
    c = np.linalg.norm(xj - xi, axis=1)
    area = np.linalg.norm(face_area_vectors(vertices, faces), axis=1)
    s = 0.5 * (a + b + c)
    inradius = area / s
    aspect = np.maximum(np.maximum(a, b), c) / (2.0 * math.sqrt(3.0) * inradius)
    cosA = np.clip((b**2 + c**2 - a**2) / (2 * b * c), -1, 1)
    cosB = np.clip((a**2 + c**2 - b**2) / (2 * a * c), -1, 1)
    angles = np.degrees(np.stack([np.arccos(cosA), np.arccos(cosB)], axis=1))
    angles = np.concatenate([angles, 180.0 - angles.sum(axis=1, keepdims=True)], axis=1)
    return {
        "n_vertices": int(len(vertices)),
        "n_faces": int(len(faces)),
        "edge_min": float(L.min()),
        "edge_mean": float(L.mean()),
        "edge_max": float(L.max()),
        "edge_spread": float(L.std() / L.mean()),
        "aspect_mean": float(aspect.mean()),
        "aspect_max": float(aspect.max()),
        "angle_min_deg": float(angles.min()),
        "angle_max_deg": float(angles.max()),
    }


# --------------------------------------------------------------------------- unit-sphere families
def icosphere(level: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere: 10 * 4^level + 2 vertices, 20 * 4^level faces, outward orientation."""
    check_range("level", level, 0, MAX_ICOSPHERE_LEVEL, integer=True)
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = np.array(
        [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
        dtype=float,
    )
    f = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]],
        dtype=np.int64,
    )
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(int(level)):
        v, f = _subdivide(v, f)
    return v, f


def _subdivide(v, f):
    """Split each triangle into four, midpoints shared through a unique-edge table, projected to the sphere."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    es = np.sort(e, axis=1)
    uniq, inv = np.unique(es, axis=0, return_inverse=True)
    mid = 0.5 * (v[uniq[:, 0]] + v[uniq[:, 1]])
    mid /= np.linalg.norm(mid, axis=1, keepdims=True)
    nf = len(f)
    m = inv.reshape(3, nf).T + len(v)  # midpoint index of edges (01, 12, 20)
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    m01, m12, m20 = m[:, 0], m[:, 1], m[:, 2]
    new_f = np.concatenate([
        np.stack([a, m01, m20], 1), np.stack([b, m12, m01], 1),
        np.stack([c, m20, m12], 1), np.stack([m01, m12, m20], 1),
    ])
    return np.vstack([v, mid]), new_f


def quasiuniform_sphere(n_vertices: int, seed: int = 0, lloyd_steps: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Unit sphere mesh without global symmetry: a jittered Fibonacci lattice, triangulated by its convex
    hull, relaxed by ``lloyd_steps`` centroidal (Lloyd) steps so edge lengths are even.

    The jitter (set by ``seed``) breaks the lattice's spiral symmetry; the seed is recorded in the mesh.
    """
    check_range("n_vertices", n_vertices, 12, 20_000_000, integer=True)
    check_range("lloyd_steps", lloyd_steps, 0, 1000, integer=True)
    from scipy.spatial import ConvexHull

    n = int(n_vertices)
    rng = np.random.default_rng(seed)
    i = np.arange(n) + 0.5
    golden = math.pi * (3.0 - math.sqrt(5.0))
    spacing = math.sqrt(4.0 * math.pi / n)
    z = 1.0 - 2.0 * i / n
    phi_ = golden * i
    r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    p = np.stack([r * np.cos(phi_), r * np.sin(phi_), z], axis=1)
    p += 0.25 * spacing * rng.standard_normal(p.shape)
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    f = _hull_faces(p, ConvexHull)
    for _ in range(int(lloyd_steps)):
        # centroidal step on the sphere: each vertex moves to the area-weighted mean of its
        # triangles' centroids, approximating the centroid of its Voronoi cell
        cen = p[f].mean(axis=1)
        w = 2.0 * np.linalg.norm(face_area_vectors(p, f), axis=1)  # twice the area, as the weights always were
        acc = np.zeros_like(p)
        wsum = np.zeros(n)
        for k in range(3):
            np.add.at(acc, f[:, k], cen * w[:, None])
            np.add.at(wsum, f[:, k], w)
        p = acc / wsum[:, None]
        p /= np.linalg.norm(p, axis=1, keepdims=True)
        f = _hull_faces(p, ConvexHull)
    return p, f


def _hull_faces(p, ConvexHull):
    f = ConvexHull(p).simplices.astype(np.int64)
    flip = dot_rows(face_area_vectors(p, f), p[f].mean(axis=1)) < 0
    f[flip] = f[flip][:, [0, 2, 1]]
    return f


# --------------------------------------------------------------------------- ellipsoids
def _validate_axes(axes):
    axes = tuple(float(a) for a in axes)
    if len(axes) != 3:
        raise ConfigError(f"axes must have three entries a:b:c, got {axes}")
    for name, a in zip("abc", axes, strict=True):
        check_range(f"axes ratio {name}", a, 0.0, None, lo_open=True)
    return axes


def ellipsoid_from_sphere(unit_vertices, faces, axes=(1.0, 0.8, 1.0), R=1.0):
    """Stretch a unit-sphere mesh along x, y, z by ``axes`` and rescale it so that the *meshed* volume equals
    4/3 pi R^3 (the vesicle's equivalent radius is then exactly R)."""
    axes = _validate_axes(axes)
    check_range("radius", R, 0.0, None, lo_open=True)
    v = unit_vertices * np.asarray(axes)[None, :]
    vol = enclosed_volume(v, faces)
    v *= (4.0 / 3.0 * math.pi * R**3 / vol) ** (1.0 / 3.0)
    return v


def unit_sphere(family="icosphere", level=4, n_vertices=None, seed=0, lloyd_steps=8):
    if family == "icosphere":
        return icosphere(level)
    if family == "quasiuniform":
        if n_vertices is None:
            n_vertices = 10 * 4 ** int(check_range("level", level, 0, MAX_ICOSPHERE_LEVEL, integer=True)) + 2
        return quasiuniform_sphere(n_vertices, seed=seed, lloyd_steps=lloyd_steps)
    raise ConfigError(f"family must be one of {FAMILIES}, got {family!r}")


def axes_for_delta(target_delta, unit_vertices, faces, vary="b", fixed=(1.0, 1.0, 1.0), max_ratio=10.0):
    """Axes ratio (one axis varied, default b in 1:b:1, b < 1) whose meshed excess area equals target_delta.

    Solved on the given mesh, so the faceting's own area is included. Raises ConfigError if the target is
    below the mesh's sphere value or cannot be reached with the ratio in [1/max_ratio, 1].
    """
    from scipy.optimize import brentq

    check_range("target_delta", target_delta, 0.0, None)
    k = "abc".index(vary)

    def delta_of(s):
        ax = list(fixed)
        ax[k] = s
        v = ellipsoid_from_sphere(unit_vertices, faces, ax, 1.0)
        return surface_area(v, faces) - 4.0 * math.pi - target_delta

    lo, hi = 1.0 / max_ratio, 1.0
    f_hi = delta_of(hi)
    if f_hi > 0:
        raise ConfigError(
            f"target delta {target_delta:g} is below this mesh's own sphere excess area {f_hi + target_delta:.4g}; "
            "refine the mesh (higher level or more vertices)"
        )
    if delta_of(lo) < 0:
        raise ConfigError(f"target delta {target_delta:g} needs an axes ratio below 1/{max_ratio:g}")
    s = brentq(delta_of, lo, hi, xtol=1e-12)
    ax = list(fixed)
    ax[k] = s
    return tuple(ax)


def make_vesicle(
    family="icosphere", level=4, axes=(1.0, 0.8, 1.0), R=1.0, target_delta=None, n_vertices=None,
    seed=0, lloyd_steps=8,
) -> Mesh:
    """Build a vesicle mesh: unit sphere of the chosen family -> ellipsoid -> volume of a sphere of radius R.

    With ``target_delta`` the middle axis b of 1:b:1 is solved for so the meshed Delta matches it.
    """
    check_range("radius", R, 0.0, None, lo_open=True)
    u, f = unit_sphere(family, level, n_vertices, seed, lloyd_steps)
    if target_delta is not None:
        axes = axes_for_delta(target_delta, u, f)
    axes = _validate_axes(axes)
    v = ellipsoid_from_sphere(u, f, axes, R)
    m = Mesh(v, f)
    m.check()
    m.attrs.update(
        family=family,
        n_vertices=m.n_vertices,
        level=int(level) if family == "icosphere" else -1,
        seed=int(seed) if family == "quasiuniform" else -1,
        lloyd_steps=int(lloyd_steps) if family == "quasiuniform" else 0,
        axes_a=axes[0], axes_b=axes[1], axes_c=axes[2],
        radius=float(R),
        delta=m.excess_area(),
        area=m.area(),
        volume=m.volume(),
    )
    if target_delta is not None:
        m.attrs["target_delta"] = float(target_delta)
    return m


# --------------------------------------------------------------------------- netCDF I/O (UGRID 1.0)
#: The UGRID mesh topology of the mesh and trajectory files: a 2D triangle mesh whose node coordinates are the
#: vertex directions (node_lon, node_lat) seen from the centroid; the Cartesian positions node_x/y/z are fields
#: on its nodes (time-dependent in a trajectory). UGRID readers (xugrid, uxarray) open the files with it.
UGRID_TOPOLOGY = {
    "cf_role": "mesh_topology",
    "long_name": "topology of the triangulated membrane (a closed surface: nodes placed by their direction)",
    "topology_dimension": 2,
    "node_coordinates": "node_lon node_lat",
    "face_node_connectivity": "face_node_connectivity",
    "node_dimension": "n_node",
    "face_dimension": "n_face",
}


def node_lonlat(vertices) -> tuple[np.ndarray, np.ndarray]:
    """Longitude and latitude (degrees) of each vertex's direction from the vertex centroid: the node coordinates
    of the UGRID topology (a star-shaped closed surface maps one to one onto the sphere)."""
    d = np.asarray(vertices, dtype=float)
    d = d - d.mean(axis=0)
    r = np.linalg.norm(d, axis=1)
    lon = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    lat = np.degrees(np.arcsin(np.clip(d[:, 2] / np.where(r > 0, r, 1.0), -1.0, 1.0)))
    return lon, lat


def ugrid_variables(vertices) -> dict:
    """The UGRID variables other than the connectivity: the topology ``mesh`` and node_lon/node_lat of
    ``vertices`` (V, 3), as xarray (dims, data, attrs) tuples."""
    lon, lat = node_lonlat(vertices)
    return {
        "mesh": ((), np.int32(0), dict(UGRID_TOPOLOGY)),
        "node_lon": (("n_node",), lon, {
            "standard_name": "longitude", "units": "degrees_east",
            "long_name": "azimuth of the vertex direction from the centroid (x towards 0, y towards 90)"}),
        "node_lat": (("n_node",), lat, {
            "standard_name": "latitude", "units": "degrees_north",
            "long_name": "elevation of the vertex direction from the centroid above the x-y plane"}),
    }


#: attributes of the connectivity and of node fields in UGRID files
FACE_NODE_ATTRS = {"cf_role": "face_node_connectivity", "start_index": 0,
                   "long_name": "vertices of each triangle, counter-clockwise seen from outside"}
NODE_FIELD_ATTRS = {"mesh": "mesh", "location": "node"}
FACE_FIELD_ATTRS = {"mesh": "mesh", "location": "face"}


def to_dataset(mesh: Mesh):
    import xarray as xr

    from .. import __version__
    from ..model.units import SCALE_ATTRS, cf_unit_attrs

    v, f = mesh.vertices, mesh.faces
    ds = xr.Dataset(
        {
            **ugrid_variables(v),
            **{f"node_{c}": (("n_node",), v[:, i], cf_unit_attrs({"units": "R", "long_name": f"vertex {c}",
                                                                  **NODE_FIELD_ATTRS}))
               for i, c in enumerate("xyz")},
            "face_node_connectivity": (("n_face", "n_vertex_per_face"), f.astype(np.int32), dict(FACE_NODE_ATTRS)),
        },
        attrs={
            "Conventions": "CF-1.10 UGRID-1.0",
            "title": "vesicle membrane mesh",
            "source": f"vesicle_core {__version__}",
            **SCALE_ATTRS,
            **{k: (v_ if not isinstance(v_, bool) else int(v_)) for k, v_ in mesh.attrs.items()},
        },
    )
    return ds


def save(mesh: Mesh, path) -> None:
    """Write the mesh to netCDF atomically (temp file + rename)."""
    from ..io import atomic_to_netcdf

    atomic_to_netcdf(to_dataset(mesh), path)


def load(path) -> Mesh:
    """Read a mesh written by :func:`save`; raises MeshError naming the file if it is not a valid mesh."""
    import xarray as xr

    try:
        with xr.open_dataset(path) as ds:
            v = np.stack([ds["node_x"].values, ds["node_y"].values, ds["node_z"].values], axis=1).astype(float)
            f = ds["face_node_connectivity"].values.astype(np.int64)
            attrs = dict(ds.attrs)
    except FileNotFoundError:
        raise MeshError(f"mesh file {path} does not exist") from None
    except (KeyError, OSError, ValueError) as exc:
        raise MeshError(f"{path} is not a vesicle mesh file (need node_x/y/z and face_node_connectivity): "
                        f"{exc}") from None
    from ..model.units import SCALE_ATTRS

    for k in ("Conventions", "title", "source", *SCALE_ATTRS):
        attrs.pop(k, None)
    try:
        check_closed_surface(v, f)
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None
    return Mesh(v, f, attrs)
