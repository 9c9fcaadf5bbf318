"""``vesicle microscope``: what a phase-contrast microscope focused on the flow's plane sees of a trajectory.

Per analysed snapshot: the exact section (:mod:`section`), its image (:mod:`micrograph`), the outline read back
from the image along rays, and the spectra of both outlines detrended by the section of the fitted ellipsoid
(:mod:`contour_spectrum`). The fitted ellipsoids are taken from a spectra.nc of the same trajectory where its
times match (``vesicle decompose`` already fits them), else fitted here.

The wrinkle morphology of the 3D membrane (:mod:`.morphology_series`: metrics, pattern class and where the wrinkle
energy sits) at fewer frames, on the dimension morph_time: every ``morphology_stride``-th frame of the reversed flow,
t_* and the paper's snapshot times; k_*(t) of the outline at every analysed frame.

Layout of the result -- coords: time, [t_tau], theta (the rays), k (0..n_theta / 2), sector (centres of the angular
bins), [image_time, y, x for the stored images], morph_time, level, scale, band. Variables without suffix describe
the outline read from the image (what the experimenter measures); ``_section`` ones the exact section (what an ideal
microscope would see). The cost: attrs microscope_wall_time_s (outlines), morphology_wall_time_s and, with the run's
own wall_time_s, cost_fraction = their sum / wall_time_s. See docs/reference/datasets.md, "microscope.nc".
"""

from __future__ import annotations

import math
import time as time_module

import numpy as np
import xarray as xr

from ..data.datasets import _connectivity, cf_attrs, netcdf_safe_attrs, validate_trajectory
from ..errors import check_range
from ..geometry.surface import resolvable_l_max
from . import contour_spectrum as CS
from .micrograph import Optics, radial_contour, render
from .morphology_series import PAPER_TIMES, frame_morphology, morphology_frames, morphology_variables
from .pattern_synth import CLASSES
from .section import main_section, plane
from .shape import fit_ellipsoid

__all__ = ["DEFAULT_RADIUS_UM", "default_radius_um", "microscope_from_trajectory"]

#: the equivalent radii of Sec. V: quasi-spherical (Delta = 0.116) and elongated (Delta ~ 1) vesicles
DEFAULT_RADIUS_UM = {"quasispherical": 16.71, "elongated": 18.0}
SEARCH = 0.25  # R: half-width of the band about the fitted ellipse searched for the outline


def default_radius_um(delta: float) -> float:
    """R in micrometres of the paper's vesicle of excess area ``delta``: 16.71 um below Delta = 0.5, else 18 um."""
    return DEFAULT_RADIUS_UM["quasispherical" if delta < 0.5 else "elongated"]


def _vertices(traj, k):
    return np.stack([np.asarray(traj[c].isel(time=k).values, float) for c in ("node_x", "node_y", "node_z")], 1)


def _face_tension(traj, k):
    return np.asarray(traj["face_tension"].isel(time=k).values, float) if "face_tension" in traj else None


def _morphology(traj, faces, idx, spectra, morphology_stride):
    """The morphology at the frames of :func:`.morphology_series.morphology_frames` among the analysed ``idx``."""
    time = np.asarray(traj["time"].values, float)[idx]
    # t_* is spectra.nc's (argmin Delta_2): without it, no frame is marked as t_*
    t_star = float(spectra["t_star"]) if spectra is not None and "t_star" in spectra else None
    frames = morphology_frames(time, t_star, morphology_stride, PAPER_TIMES)
    results = []
    for j in frames["index"]:
        k = int(idx[j])
        v = _vertices(traj, k)
        results.append(frame_morphology(v, faces, _ellipsoid(spectra, time[j], v), _face_tension(traj, k)))
    data, coords = morphology_variables(results, time, frames)
    attrs = {"morphology_stride": int(morphology_stride), "t_star": t_star if t_star is not None else math.nan,
             "paper_times": [float(t) for t in frames["paper"]], "paper_times_outside": frames["paper_outside"]}
    if frames["t_star"] >= 0:
        attrs["pattern_at_t_star"] = results[list(frames["index"]).index(frames["t_star"])]["pattern"]
    return data, coords, attrs


def _ellipsoid(spectra, t, vertices):
    if spectra is not None and "ellipsoid_center" in spectra:
        times = np.asarray(spectra["time"].values, float)
        j = int(np.argmin(np.abs(times - t)))
        if abs(times[j] - t) <= 1e-9 * max(1.0, abs(t)):
            return tuple(np.asarray(spectra[n].isel(time=j).values, float)
                         for n in ("ellipsoid_center", "ellipsoid_axes", "ellipsoid_rotation"))
    return fit_ellipsoid(vertices)


def _frame(v, faces, where, ellipsoid, optics, radius_um, half_width, theta, opts):
    """Section, image and both spectra of one snapshot -> dict of per-frame results."""
    contour = main_section(v, faces, where)
    center = where.to_plane(np.asarray(ellipsoid[0], float)[None])[0]
    rho = CS.ellipsoid_section_radius(where, ellipsoid, center, theta)
    r_sec, star = CS.radius_on_rays(contour.uv, center, theta)
    img = render(v, faces, where, optics, length_um=radius_um, half_width=half_width, center_uv=center)
    # search a band of +-SEARCH about the fitted ellipse: wider than any wrinkle, narrow enough to be cheap
    r_img = radial_contour(img, center, theta, np.maximum(rho - SEARCH, 0.0), rho + SEARCH)
    out = {"image": img, "rho": rho, "r_section": r_sec, "r_image": r_img, "star_shaped": star,
           "mismatch_px": float(np.sqrt(np.mean((r_img - r_sec) ** 2)) / img.pixel)}
    for suffix, r in (("", r_img), ("_section", r_sec)):
        out[suffix] = CS.profile_spectrum(theta, r - rho, **opts)
    return out


def _var(dims, data, units, long_name, **extra):
    return (dims, data, {"units": units, "long_name": long_name, **extra})


def _half_width(traj, faces, where, idx):
    """Half the side of the images: 1.2 x the largest distance of any section point from the origin."""
    reach = max(float(np.abs(main_section(_vertices(traj, k), faces, where).uv).max()) for k in idx)
    return 1.2 * reach


def _dataset(frames, traj, idx, theta, image_idx, n_bins):
    time = np.asarray(traj["time"].values, float)[idx]
    data = {}
    for suffix, what in (("", "the outline read from the image"), ("_section", "the exact section")):
        s = [f[suffix] for f in frames]
        data[f"k_star{suffix}"] = _var("time", [x.k_star for x in s], "1", f"k_* of {what} (2D eq. 31, k >= 3)")
        data[f"k_rms{suffix}"] = _var("time", [x.k_rms for x in s], "1", f"rms wavenumber of {what} (k >= 0)")
        data[f"up_crossings{suffix}"] = _var("time", np.array([x.up_crossings for x in s], np.int32), "1",
                                             f"upward crossings of the ellipsoid's section by {what}")
        data[f"crests{suffix}"] = _var("time", np.array([x.crests for x in s], np.int32), "1",
                                       f"crests (maxima) of {what}")
        data[f"wrinkle_rms{suffix}"] = _var("time", [x.wrinkle_rms for x in s], "R",
                                            f"rms of the k >= 3 part of {what}")
        data[f"power{suffix}"] = _var(("time", "k"), np.array([x.power for x in s]), "R^2",
                                      f"power spectrum |c_k|^2 of the radial deviation of {what}")
        data[f"variance_by_angle{suffix}"] = _var(("time", "sector"), np.array([x.variance_by_angle for x in s]),
                                                  "R^2", f"mean square of the wrinkles (k >= 3) of {what} per sector")
    data["radius"] = _var(("time", "theta"), np.array([f["r_image"] for f in frames]), "R",
                          "radius of the image's outline about the ellipsoid's centre")
    data["radius_section"] = _var(("time", "theta"), np.array([f["r_section"] for f in frames]), "R",
                                  "radius of the exact section (outermost crossing)")
    data["radius_ellipsoid"] = _var(("time", "theta"), np.array([f["rho"] for f in frames]), "R",
                                    "radius of the fitted ellipsoid's section (the reference level)")
    data["outline_mismatch"] = _var("time", [f["mismatch_px"] for f in frames], "1",
                                    "rms distance between the image's outline and the exact section, in pixels")
    data["star_shaped"] = _var("time", np.array([f["star_shaped"] for f in frames], np.int8), "1",
                               "1 if every ray crosses the section once")
    if image_idx:
        pix = np.array([frames[i]["image"].pixels for i in image_idx], np.float32)
        data["image"] = _var(("image_time", "y", "x"), pix, "1", "intensity (background 1, membrane dark)")
        data["image_origin"] = _var(("image_time", "uv"), np.array([frames[i]["image"].origin_uv
                                                                   for i in image_idx]), "R",
                                    "in-plane position of pixel (0, 0)'s centre")
    coords = {"time": ("time", time, dict(traj["time"].attrs)),
              "theta": ("theta", theta, {"units": "rad", "long_name": "angle of the ray from e1 (the x axis)"}),
              "k": ("k", np.arange(len(theta) // 2 + 1), {"units": "1", "long_name": "wavenumber around the outline"}),
              "sector": ("sector", (np.arange(n_bins) + 0.5) * 2 * np.pi / n_bins,
                         {"units": "rad", "long_name": "centre of the angular sector"})}
    if "t_tau" in traj.variables:
        coords["t_tau"] = ("time", np.asarray(traj["t_tau"].values, float)[idx], dict(traj["t_tau"].attrs))
    if image_idx:
        coords["image_time"] = ("image_time", time[list(image_idx)], dict(traj["time"].attrs))
    return xr.Dataset(data, coords=coords)


def _image_frames(time, n_images, image_times=None):
    """Indices of the analysed frames nearest ``image_times``, else of ``n_images`` frames evenly spread over
    time >= 0 (the reversed flow)."""
    if image_times is not None:
        return sorted({int(np.argmin(np.abs(time - float(t)))) for t in image_times})
    after = np.flatnonzero(time >= 0)
    if n_images == 0 or not len(after):
        return []
    return sorted(set(after[np.linspace(0, len(after) - 1, min(n_images, len(after))).round().astype(int)].tolist()))


def microscope_from_trajectory(traj: xr.Dataset, *, spectra: xr.Dataset | None = None, optics: Optics | None = None,
                               radius_um: float | None = None, offset: float = 0.0, normal=(0.0, 0.0, 1.0),
                               stride: int = 1, n_theta: int = 512, n_bins: int = 16, n_images: int = 6,
                               image_times=None, morphology_stride: int | None = 5, progress: bool = False,
                               command: str | None = None) -> xr.Dataset:
    """The virtual microscope over every ``stride``-th snapshot of ``traj`` (module docstring): focal plane at
    ``offset`` (R) along ``normal`` from the vesicle's first centre; ``radius_um`` R in micrometres (default from
    the trajectory's delta, :func:`default_radius_um`); ``n_images`` images kept in the file, or those of the frames
    nearest ``image_times`` (gamma_dot (t - t0), e.g. the times of the paper's Fig. 6); the morphology at every
    ``morphology_stride``-th analysed frame of the reversed flow, t_* and the paper's times (None: no morphology)."""
    started = time_module.perf_counter()
    optics = Optics() if optics is None else optics
    validate_trajectory(traj)
    stride = int(check_range("stride", stride, 1, None, integer=True))
    check_range("n_images", n_images, 0, 1000, integer=True)
    check_range("offset", offset, -1.5, 1.5)
    if morphology_stride is not None:
        check_range("morphology_stride", morphology_stride, 1, None, integer=True)
    faces = _connectivity(traj, "trajectory")
    idx = np.arange(0, traj.sizes["time"], stride)
    delta = float(np.asarray(traj.attrs.get("delta", 0.116)).ravel()[0])
    radius_um = default_radius_um(delta) if radius_um is None else check_range("radius_um", radius_um, 0.1, 1000.0)
    theta = 2 * np.pi * np.arange(n_theta) / n_theta
    v0 = _vertices(traj, 0)
    where = plane(normal, offset, center=v0.mean(axis=0))
    k_max = min(resolvable_l_max(v0, faces), n_theta // 2)
    opts = dict(k_max=k_max, resolution=0.25 * optics.pixel_um / radius_um, n_bins=n_bins)
    half_width = _half_width(traj, faces, where, idx)
    it = idx
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(idx, desc="microscope", unit="snapshot")
    time = np.asarray(traj["time"].values, float)
    frames = []
    for k in it:
        v = _vertices(traj, int(k))
        frames.append(_frame(v, faces, where, _ellipsoid(spectra, time[k], v), optics, radius_um, half_width,
                             theta, opts))
    ds = _dataset(frames, traj, idx, theta, _image_frames(time[idx], n_images, image_times), n_bins)
    outline_s = time_module.perf_counter() - started
    morph_attrs = {}
    if morphology_stride is not None:
        data, coords, morph_attrs = _morphology(traj, faces, idx, spectra, morphology_stride)
        ds = ds.assign_coords(coords).assign(data)
    morph_s = time_module.perf_counter() - started - outline_s
    attrs = netcdf_safe_attrs({k: v for k, v in traj.attrs.items()
                               if k not in ("Conventions", "title", "source", "history")})
    attrs.update(cf_attrs("virtual phase-contrast microscopy of a vesicle trajectory: outlines and their spectra",
                          command=command, **{f"optics_{k}": v for k, v in optics.attrs().items()},
                          radius_um=radius_um, focal_offset=float(offset), focal_normal=list(map(float, where.normal)),
                          stride=stride, n_theta=n_theta, k_max=k_max, crest_resolution=opts["resolution"],
                          k_star_min=CS.K_STAR_MIN, image_pixel=float(optics.pixel_um / radius_um),
                          image_half_width=half_width, ellipsoid_source="spectra" if spectra is not None else "fit"))
    attrs.update(netcdf_safe_attrs(morph_attrs), pattern_classes=" ".join(CLASSES), microscope_wall_time_s=outline_s,
                 morphology_wall_time_s=morph_s if morphology_stride is not None else 0.0)
    run_s = float(np.asarray(traj.attrs.get("wall_time_s", math.nan)).ravel()[0])
    attrs["cost_fraction"] = (outline_s + attrs["morphology_wall_time_s"]) / run_s if run_s > 0 else math.nan
    attrs["k_star_max"] = float(np.nanmax(ds["k_star"].values)) if np.isfinite(ds["k_star"].values).any() \
        else math.nan
    return ds.assign_attrs(attrs)
