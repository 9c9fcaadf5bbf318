"""The paper's Fig. 6 for one run, from the virtual microscope: the phase-contrast images (``vesicle microscope``)
above the 3D membrane seen along the same optical axis at the same times, and below them k_*(t) of the outline
beside l_*(t) of the 3D spectrum (eq. 31), with sqrt(l_* (l_* + 1) / 2), what the outline of an isotropic pattern
of degree l_* would show (Rice's formula; docs/explanation/microscopy.md); along the top of the l_* panel, the
pattern class of each frame whose morphology microscope.nc holds (bold: t_*).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from .plots import _case_label, _load, _mpl, save_figure
from .render import CMAP, _clim, _faces, _render, load_frame, vertex_average

__all__ = ["plot_microscope"]


def _images_row(fig, gs, mic, times):
    for j, t in enumerate(times):
        ax = fig.add_subplot(gs[0, j])
        img = mic["image"].sel(image_time=t).values
        ax.imshow(img, cmap="gray", origin="lower", vmin=0.4, vmax=1.05, interpolation="nearest")
        ax.set_title(rf"$\bar t$ = {t:.2f}", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        if j == 0:
            ax.set_ylabel("microscope")
    return len(times)


def _views_row(fig, gs, traj, times, engine):
    t_all = np.asarray(traj["time"].values, float)
    faces = _faces(traj)
    shapes = []
    for t in times:
        v, val, _ = load_frame(traj, int(np.argmin(np.abs(t_all - t))))
        shapes.append((v, vertex_average(v, faces, val)))
    clim = _clim([s[1] for s in shapes], None)
    images, _ = _render(shapes, faces, ["front"] * len(shapes), (300, 300), clim, CMAP, engine)
    for j, im in enumerate(images):
        ax = fig.add_subplot(gs[1, j])
        ax.imshow(im)
        ax.set_xticks([])
        ax.set_yticks([])
        if j == 0:
            ax.set_ylabel("3D, along z")


def _series_row(fig, gs, mic, spectra, n):
    half = max(1, n // 2)
    ax_k = fig.add_subplot(gs[2, :half])
    t = np.asarray(mic["time"].values, float)
    ax_k.plot(t, mic["k_star"].values, "k-", lw=1.2, label="$k_*$, image")
    ax_k.plot(t, mic["k_star_section"].values, "C0--", lw=1, label="$k_*$, exact section")
    ax_k.plot(t, mic["crests"].values, "C3.", ms=3, label="crests")
    ax_l = fig.add_subplot(gs[2, half:])
    if spectra is not None and "l_star_t" in spectra:
        ts = np.asarray(spectra["time"].values, float)
        ls = np.asarray(spectra["l_star_t"].values, float)
        ax_l.plot(ts, ls, "k-", lw=1.2, label="$l_*$ (eq. 31)")
        ax_k.plot(ts, np.sqrt(ls * (ls + 1) / 2), "C2:", lw=1.2, label=r"$\sqrt{l_*(l_*+1)/2}$")
    _pattern_marks(ax_l, mic)
    for ax, ylabel in ((ax_k, "wrinkles seen in focus"), (ax_l, "3D wrinkle mode")):
        ax.set_xlabel(r"$\bar t = \dot\gamma t$")
        ax.set_ylabel(ylabel)
        ax.axvline(0.0, color="0.7", lw=0.8)
        ax.legend(fontsize=7, loc="best")


#: one-letter labels of the pattern classes on the l_* panel
_MARK = {"ripples": "R", "herringbone": "H", "labyrinth": "L", "hexagons_up": "X+", "hexagons_down": "X-",
         "peanut": "P"}


def _pattern_marks(ax, mic):
    """The pattern class of each classified frame (microscope.nc's morph_time) as a letter along the top of ``ax``,
    t_* in bold."""
    if "pattern" not in mic:
        return
    names = mic.attrs.get("pattern_classes", "").split() or mic["pattern"].attrs.get("flag_meanings", "").split()
    star = np.asarray(mic["is_t_star"].values) if "is_t_star" in mic else np.zeros(mic.sizes["morph_time"])
    for t, p, s in zip(np.asarray(mic["morph_time"].values, float), mic["pattern"].values, star, strict=True):
        ax.text(t, 0.97, _MARK.get(names[int(p)], "?"), transform=ax.get_xaxis_transform(), ha="center", va="top",
                fontsize=7, fontweight="bold" if s else "normal", color="C3" if s else "0.3")
    ax.text(0.01, 0.02, "class: R ripples, H herringbone, L labyrinth, X+/X- hexagons, P peanut (bold: t_*)",
            transform=ax.transAxes, fontsize=6, color="0.3")


def plot_microscope(microscope, trajectory, spectra=None, outputs="microscope.png", *, dpi=150, engine=None):
    """Fig. 6 layout for one run (module docstring). ``microscope``, ``trajectory``, ``spectra``: datasets or
    paths; the images are those stored in microscope.nc (``vesicle microscope --n-images``)."""
    plt = _mpl()
    mic = _load(microscope, "microscope")
    spec = _load(spectra, "spectra")
    if "image" not in mic:
        raise ConfigError("microscope: the file holds no images (written with --n-images 0)")
    times = [float(t) for t in mic["image_time"].values]
    n = len(times)
    fig = plt.figure(figsize=(max(6.0, 2.0 * n), 7.0))
    gs = fig.add_gridspec(3, n, height_ratios=[1, 1, 1.1], hspace=0.35, wspace=0.3)
    _images_row(fig, gs, mic, times)
    import xarray as xr

    with xr.open_dataset(trajectory, engine="netcdf4") as traj:
        _views_row(fig, gs, traj, times, engine)
    _series_row(fig, gs, mic, spec, n)
    label = _case_label(mic)
    fig.suptitle(f"What the microscope sees{': ' + label if label else ''} "
                 f"(NA {mic.attrs.get('optics_numerical_aperture', math.nan):g}, "
                 f"{mic.attrs.get('optics_magnification', math.nan):g}x, R = "
                 f"{mic.attrs.get('radius_um', math.nan):g} um)",
                 fontsize=10)
    return save_figure(fig, outputs, dpi=dpi)
