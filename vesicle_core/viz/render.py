"""3D views of the membrane coloured by local surface tension (Figs. 6e and 7c), rendered off-screen.

    render_views(vertices, faces, values, output)       one shape from six directions: front/back along z,
                                                        left/right along y, top/bottom along x (Fig. 6e caption)
    render_snapshots(frames, faces, output)             a strip of shapes over gamma_dot t, one direction
    views_from_trajectory(path, output, time=...)       the same from a trajectory.nc (default time: t_*)
    snapshots_from_trajectory(path, output, times=...)

Engines. Each view is drawn by pyvista (VTK) off-screen when that works on the machine, else by matplotlib's
3D polygons (flat-shaded ``Poly3DCollection``, painter's algorithm): same API, same layout, lower fidelity. The
choice is ``engine="auto"`` (default; the environment variable ``VESICLE_RENDER`` = pyvista | matplotlib | auto
overrides it). "auto" first renders a tiny scene with pyvista in a *subprocess* (a VTK without an off-screen
context can abort the whole process), once per process. The views are then laid out, titled and given one
colour bar with matplotlib, so both engines produce the same figure. On the development machine (VTK 9.7, no
X server) pyvista renders off-screen.

Colours: local tension per triangle [kappa/R^2] on a diverging map centred at zero (blue: compressed, negative
tension; red: stretched), clipped at the 98th percentile of |tension| unless ``clim`` is given.
"""

from __future__ import annotations

import logging
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from ..errors import ConfigError, require
from ..geometry import surface

__all__ = [
    "VIEWS",
    "render_views",
    "render_snapshots",
    "views_from_trajectory",
    "snapshots_from_trajectory",
    "load_frame",
    "snapshot_times",
    "pyvista_works",
    "select_engine",
]

log = logging.getLogger("vesicle_core.viz.render")

#: view name -> (direction from the centre to the camera, camera up vector). Fig. 6e: front/back along z,
#: left/right along y, top/bottom along x.
VIEWS = {
    "front": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "back": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "left": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    "right": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "top": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "bottom": ((-1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
}
SIX = ("front", "back", "left", "right", "top", "bottom")
CMAP = "coolwarm"

_PROBE = (
    "import pyvista as pv\n"
    "p = pv.Plotter(off_screen=True, window_size=(64, 64))\n"
    "p.add_mesh(pv.Sphere())\n"
    "img = p.screenshot(return_img=True)\n"
    "p.close()\n"
    "assert img is not None and img.std() > 0\n"
    "print('ok')\n"
)
_PYVISTA_OK: bool | None = None


def pyvista_works(timeout: float = 90.0) -> bool:
    """True when pyvista can render off-screen here (probed once per process, in a subprocess)."""
    global _PYVISTA_OK
    if _PYVISTA_OK is None:
        try:
            r = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=timeout,
                               env={**os.environ, "PYVISTA_OFF_SCREEN": "true"})
            _PYVISTA_OK = r.returncode == 0 and "ok" in r.stdout
            if not _PYVISTA_OK:
                log.warning("pyvista cannot render off-screen here (%s); using matplotlib",
                            (r.stderr.strip().splitlines() or ["no message"])[-1])
        except (OSError, subprocess.TimeoutExpired) as exc:
            log.warning("pyvista probe failed (%s); using matplotlib", exc)
            _PYVISTA_OK = False
    return _PYVISTA_OK


def select_engine(engine: str | None = None) -> str:
    """'pyvista' or 'matplotlib' for engine = 'auto' | 'pyvista' | 'matplotlib' (None: $VESICLE_RENDER or auto)."""
    engine = (engine or os.environ.get("VESICLE_RENDER") or "auto").lower()
    if engine not in ("auto", "pyvista", "matplotlib"):
        raise ConfigError(f"render engine must be 'auto', 'pyvista' or 'matplotlib', got {engine!r}")
    if engine == "auto":
        return "pyvista" if pyvista_works() else "matplotlib"
    if engine == "pyvista":
        require("pyvista", "viz", "the render engine 'pyvista'")
    return engine


# --------------------------------------------------------------------------- one image per view
def _check_mesh(vertices, faces, values):
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ConfigError(f"vertices must have shape (n, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or f.size == 0 or f.min() < 0 or f.max() >= len(v):
        raise ConfigError("faces must be (m, 3) vertex indices into vertices")
    val = np.asarray(values, dtype=float).ravel()
    if val.size != len(f):
        raise ConfigError(f"one value per face expected ({len(f)}), got {val.size}")
    return v, f, val


def vertex_average(vertices, faces, face_values):
    """Area-weighted mean of the face values around each vertex, (n,): the smooth field the renders colour by.

    A per-triangle tension carries a mesh-scale alternation that hides the wrinkles; its vertex average is the
    field on the scale the wrinkles live on (Figs. 6e, 7c).
    """
    return surface.vertex_average(*_check_mesh(vertices, faces, face_values))


def _pyvista_images(shapes, faces, views, px, clim, cmap, extent):
    import pyvista as pv

    f = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
    pl = pv.Plotter(off_screen=True, window_size=(int(px[0]), int(px[1])))
    pl.set_background("white")
    images = []
    try:
        for (verts, vals), view in zip(shapes, views, strict=True):
            pl.clear_actors()
            mesh = pv.PolyData(verts, f)
            smooth = len(vals) == len(verts)  # vertex values: interpolated colours and Phong normals
            (mesh.point_data if smooth else mesh.cell_data)["tension"] = vals
            pl.add_mesh(mesh, scalars="tension", cmap=cmap, clim=clim, show_scalar_bar=False, smooth_shading=smooth,
                        show_edges=False)
            d, up = VIEWS[view]
            c = verts.mean(axis=0)
            pl.camera_position = [tuple(c + 10.0 * extent * np.asarray(d)), tuple(c), up]
            pl.enable_parallel_projection()
            pl.camera.parallel_scale = 0.55 * extent * max(1.0, px[1] / px[0])  # fits width and height
            pl.reset_camera_clipping_range()
            pl.render()  # without it, off-screen screenshots lag one camera change behind
            images.append(np.asarray(pl.screenshot(return_img=True)).copy())
    finally:
        pl.close()
    return images


def _mpl_images(shapes, faces, views, px, clim, cmap, extent):
    """3D polygons drawn with matplotlib into images of px pixels (the fallback engine). With vertex values each
    triangle takes the mean of its corners' colours and the shading of its corners' normals (no interpolation
    inside a triangle, but no mesh-scale alternation either)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.colors import Normalize
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    cm = plt.get_cmap(cmap)
    norm = Normalize(vmin=clim[0], vmax=clim[1])
    images = []
    for (verts, vals), view in zip(shapes, views, strict=True):
        d, up = (np.asarray(a, dtype=float) for a in VIEWS[view])
        tri = verts[faces] - verts.mean(axis=0)
        n = surface.face_normals(verts, faces)
        light = d + 0.35 * up
        light /= np.linalg.norm(light)
        if len(vals) == len(verts):
            vn = surface.vertex_normals(verts, faces)
            shade = (0.35 + 0.65 * np.clip(vn @ light, 0.0, 1.0))[faces].mean(axis=1)
            rgba = cm(norm(np.asarray(vals)[faces].mean(axis=1)))
        else:
            shade = 0.35 + 0.65 * np.clip(n @ light, 0.0, 1.0)
            rgba = cm(norm(vals))
        rgba[:, :3] *= shade[:, None]
        visible = n @ d > -0.05  # back faces are hidden anyway; dropping them speeds up the painter
        dpi = 100
        fig = plt.figure(figsize=(px[0] / dpi, px[1] / dpi), dpi=dpi)
        ax = fig.add_axes([0, 0, 1, 1], projection="3d")
        ax.add_collection3d(Poly3DCollection(tri[visible], facecolors=rgba[visible], edgecolors="none",
                                             linewidths=0))
        r = 0.55 * extent
        ax.set_xlim(-r, r)
        ax.set_ylim(-r, r)
        ax.set_zlim(-r, r)
        ax.set_box_aspect((1, 1, 1), zoom=1.6)
        ax.set_proj_type("ortho")
        elev = math.degrees(math.asin(max(-1.0, min(1.0, d[2]))))
        azim = math.degrees(math.atan2(d[1], d[0])) if abs(d[2]) < 0.999 else -90.0
        roll = 0.0
        if view == "back":
            azim = 90.0
        if view in ("top", "bottom"):
            roll = 90.0 if view == "top" else -90.0
        ax.view_init(elev=elev, azim=azim, roll=roll)
        ax.set_axis_off()
        fig.canvas.draw()
        images.append(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy())
        plt.close(fig)
    return images


def _render(shapes, faces, views, px, clim, cmap, engine):
    require("matplotlib", "viz", "rendering")  # both engines: matplotlib composes the figure
    extent = max(float(np.ptp(v, axis=0).max()) for v, _ in shapes)
    eng = select_engine(engine)
    if eng == "pyvista":
        try:
            return _pyvista_images(shapes, faces, views, px, clim, cmap, extent), eng
        except Exception as exc:  # e.g. a context that the probe got but this process did not
            if engine == "pyvista":
                raise
            log.warning("pyvista rendering failed (%s); using matplotlib", exc)
    return _mpl_images(shapes, faces, views, px, clim, cmap, extent), "matplotlib"


def _clim(values, clim):
    if clim is not None:
        lo, hi = float(clim[0]), float(clim[1])
        if not hi > lo:
            raise ConfigError(f"clim must be (low, high) with high > low, got {clim}")
        return lo, hi
    a = np.abs(np.concatenate([np.ravel(v) for v in values]))
    a = a[np.isfinite(a)]
    m = float(np.percentile(a, 98)) if a.size else 1.0
    m = m if m > 0 else 1.0
    return -m, m


def _compose(images, titles, nrows, ncols, clim, cmap, output, suptitle, label, dpi=150):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    h, w = images[0].shape[:2]
    fig_w = ncols * w / dpi + 1.2
    fig_h = nrows * h / dpi + 0.6
    fig, axes = plt.subplots(nrows, ncols, figsize=(fig_w, fig_h), dpi=dpi, squeeze=False, constrained_layout=True)
    for ax in axes.ravel():
        ax.set_axis_off()
    for ax, img, title in zip(axes.ravel(), images, titles, strict=False):  # the grid may have spare cells
        ax.imshow(img)
        ax.set_title(title, fontsize=10)
    sm = ScalarMappable(norm=Normalize(*clim), cmap=cmap)
    fig.colorbar(sm, ax=axes.ravel().tolist(), shrink=0.8, label=label)
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=dpi)
    plt.close(fig)
    return output


def render_views(vertices, faces, values, output, *, views=SIX, size=(1500, 1000), clim=None, cmap=CMAP,
                 title=None, engine=None, label=r"local tension  [$\kappa/R^2$]", smooth=True):
    """One shape from several directions (default the six of Fig. 6e) in a 2 x 3 grid, one colour bar.

    values: one number per face (local tension). smooth: colour by its vertex average (:func:`vertex_average`)
    with smooth shading, as the paper's figures; False draws the raw per-triangle values flat. size: pixel size
    of the whole grid. Returns the PNG path.
    """
    v, f, val = _check_mesh(vertices, faces, values)
    if smooth:
        val = vertex_average(v, f, val)
    views = tuple(views)
    for name in views:
        if name not in VIEWS:
            raise ConfigError(f"unknown view {name!r}; choose from {', '.join(VIEWS)}")
    ncols = min(3, len(views))
    nrows = math.ceil(len(views) / ncols)
    px = (max(64, int(size[0]) // ncols), max(64, int(size[1]) // nrows))
    cl = _clim([val], clim)
    images, eng = _render([(v, val)] * len(views), f, views, px, cl, cmap, engine)
    log.info("rendered %d views with %s", len(views), eng)
    return _compose(images, list(views), nrows, ncols, cl, cmap, output, title, label)


def render_snapshots(frames, faces, output, *, view="front", frame_size=(400, 400), clim=None, cmap=CMAP,
                     title=None, engine=None, label=r"local tension  [$\kappa/R^2$]", smooth=True):
    """A strip of shapes from one direction. frames: list of (vertices, face values, label); frame_size: pixel
    size of each frame; smooth as in :func:`render_views`."""
    if not frames:
        raise ConfigError("no frames to render")
    if view not in VIEWS:
        raise ConfigError(f"unknown view {view!r}; choose from {', '.join(VIEWS)}")
    shapes, labels = [], []
    f = None
    for verts, vals, lab in frames:
        v, f, val = _check_mesh(verts, faces, vals)
        shapes.append((v, vertex_average(v, f, val) if smooth else val))
        labels.append(str(lab))
    n = len(shapes)
    px = (max(64, int(frame_size[0])), max(64, int(frame_size[1])))
    cl = _clim([s[1] for s in shapes], clim)
    images, eng = _render(shapes, f, [view] * n, px, cl, cmap, engine)
    log.info("rendered %d snapshots with %s", n, eng)
    return _compose(images, labels, 1, n, cl, cmap, output, title, label)


# --------------------------------------------------------------------------- from a trajectory
def _open_traj(path):
    import xarray as xr

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: trajectory does not exist")
    return xr.open_dataset(path, engine="netcdf4")


def _faces(ds):
    fc = ds["face_node_connectivity"]
    return np.asarray(fc.values).astype(np.int64) - int(fc.attrs.get("start_index", 0))


def load_frame(ds, index):
    """(vertices (n, 3), face tension (m,), time) of frame ``index`` of an open trajectory Dataset."""
    v = np.stack([np.asarray(ds[c].isel(time=index).values, dtype=float) for c in ("node_x", "node_y", "node_z")],
                 axis=1)
    if "face_tension" in ds:
        val = np.asarray(ds["face_tension"].isel(time=index).values, dtype=float)
    else:
        val = np.zeros(ds.sizes["n_face"])
    return v, val, float(ds["time"].values[index])


def _t_star(spectra):
    if spectra is None:
        return math.nan
    import xarray as xr

    with xr.open_dataset(spectra, engine="netcdf4") as s:
        return float(s["t_star"].values) if "t_star" in s else math.nan


def _label(ds):
    parts = []
    for key, fmt in (("S", "S = {:.5g}"), ("chi", "$\\chi$ = {:.4g}"), ("N", "N = {:d}")):
        if key in ds.attrs:
            try:
                val = np.asarray(ds.attrs[key]).ravel()[0]
                parts.append(fmt.format(int(val) if key == "N" else float(val)))
            except (TypeError, ValueError, IndexError):
                pass
    return ", ".join(parts)


def views_from_trajectory(trajectory, output, *, time=None, spectra=None, size=(1500, 1000), clim=None,
                          engine=None):
    """Six views of the frame nearest to ``time`` (gamma_dot (t - t0)); default: t_* from ``spectra``, else the
    last frame."""
    with _open_traj(trajectory) as ds:
        t = np.asarray(ds["time"].values, dtype=float)
        target = time if time is not None else _t_star(spectra)
        if target is None or not math.isfinite(target):
            i = len(t) - 1
            what = "last frame"
        else:
            i = int(np.argmin(np.abs(t - float(target))))
            what = "t_*" if time is None else "requested time"
        v, val, ti = load_frame(ds, i)
        faces = _faces(ds)
        title = f"{_label(ds)}   $\\dot\\gamma (t - t_0)$ = {ti:.3g} ({what})"
    return render_views(v, faces, val, output, size=size, clim=clim, title=title, engine=engine)


def snapshot_times(t, n, t_star=math.nan):
    """Default times of a snapshot strip: ``n - 1`` evenly spaced from the reversal (t = 0, or the first frame
    if the run has none) to 2 t_* (the wrinkling), then the last frame; without t_*, ``n`` evenly spaced to the
    end."""
    t = np.asarray(t, dtype=float)
    t0 = 0.0 if t.min() <= 0.0 <= t.max() else float(t.min())
    n = int(n)
    if n >= 2 and math.isfinite(t_star) and t0 < 2.0 * t_star < float(t.max()):
        return [*np.linspace(t0, 2.0 * t_star, n - 1), float(t.max())]
    return list(np.linspace(t0, float(t.max()), n))


def snapshots_from_trajectory(trajectory, output, *, times=None, n=6, spectra=None, view="front",
                              frame_size=(400, 400), clim=None, engine=None):
    """Strip of frames nearest to ``times`` (gamma_dot (t - t0)); default: :func:`snapshot_times` with t_* from
    ``spectra``."""
    with _open_traj(trajectory) as ds:
        t = np.asarray(ds["time"].values, dtype=float)
        if times is None:
            times = snapshot_times(t, n, _t_star(spectra))
        idx = []
        for x in times:
            i = int(np.argmin(np.abs(t - float(x))))
            if i not in idx:
                idx.append(i)
        faces = _faces(ds)
        frames = []
        for i in idx:
            v, val, ti = load_frame(ds, i)
            frames.append((v, val, f"$\\dot\\gamma (t - t_0)$ = {ti:.3g}"))
        title = f"{_label(ds)}   view: {view}"
    return render_snapshots(frames, faces, output, view=view, frame_size=frame_size, clim=clim, title=title,
                            engine=engine)
