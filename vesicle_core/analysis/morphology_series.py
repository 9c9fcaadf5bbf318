"""The wrinkle morphology of a trajectory over time: at chosen frames, the metrics of :mod:`.morphology`, the pattern
class of :mod:`.pattern_class` and where the wrinkle energy sits against the local tension (:mod:`.wrinkle_location`).

Which frames. The metrics cost ~1 s per frame on a 9512-vertex mesh (three sparse factorisations for the crest
order at three scales), about four times the microscope's outline of the same frame, so they are evaluated at:

* every ``stride``-th frame of the reversed flow (time >= 0; default every 5th, 0.1 gamma_dot t at the runs'
  output_every 0.02): the time series;
* t_* (the frame where Delta_2 is smallest, Sec. V.A, from spectra.nc), the frame the paper's l_* describes;
* the frames nearest the paper's snapshot times of Figs. 6-8 (:data:`PAPER_TIMES`) that lie inside the run.

k_*(t) of the outline (:mod:`.microscope`) stays at every analysed frame: it is cheap and its time series is what
an experimenter measures. The height field is A_p about the ellipsoid that ``vesicle decompose`` fitted to the same
frame (the fit of :func:`.morphology.height_about_ellipsoid`), so nothing is fitted twice.

Wrinkle location: latitude bands about the compressional axis of the reversed flow, x (the vesicle's long axis
after the stretch), with the local tension of the run (face_tension). One heat smoother at one wavelength serves
both the crest order's middle scale and the energy density of :func:`.wrinkle_location.wrinkle_location`.
"""

from __future__ import annotations

import numpy as np

from ..errors import check_range
from .morphology import DEFAULT_LEVELS, DEFAULT_SCALES, _vertex_field, characteristic_degree, morphology_metrics
from .pattern_class import classify_features
from .pattern_synth import CLASSES
from .shape import wrinkle_amplitude
from .surface_calculus import HeatSmoother
from .wrinkle_location import wrinkle_location

__all__ = ["PAPER_TIMES", "COMPRESSION_AXIS", "N_BANDS", "morphology_frames", "frame_morphology",
           "morphology_variables"]

#: gamma_dot t of the snapshots of the paper's Figs. 6-8 (Fig. 6e and 7c at 2.33, Fig. 6b at 1.46, Fig. 8c at 2 and
#: 2.33); the same list as config/paper_explicit.yaml's figures.snapshot_times
PAPER_TIMES = (0.0, 0.5, 1.0, 1.46, 2.0, 2.33)
#: the axis along which the reversed flow -gamma_dot (x, -y, 0) compresses the vesicle
COMPRESSION_AXIS = (1.0, 0.0, 0.0)
N_BANDS = 6


def morphology_frames(time, t_star=None, stride=5, paper_times=PAPER_TIMES) -> dict:
    """Indices into ``time`` of the frames to classify (module docstring) -> {"index": sorted array,
    "t_star": index or -1, "paper": {paper time: index} for the paper's times inside [time[0], time[-1]],
    "paper_outside": the paper's times the run does not reach}."""
    time = np.asarray(time, float)
    stride = int(check_range("morphology stride", stride, 1, None, integer=True))
    after = np.flatnonzero(time >= 0)
    chosen = set(after[::stride].tolist())
    i_star = -1
    if t_star is not None and np.isfinite(t_star) and len(time):
        i_star = int(np.argmin(np.abs(time - float(t_star))))
        chosen.add(i_star)
    half = 0.5 * float(np.median(np.diff(time))) if len(time) > 1 else 0.0
    paper, outside = {}, []
    for t in paper_times:
        if len(time) and time[0] - half <= t <= time[-1] + half:
            paper[float(t)] = int(np.argmin(np.abs(time - t)))
            chosen.add(paper[float(t)])
        else:
            outside.append(float(t))
    return {"index": np.array(sorted(chosen), int), "t_star": i_star, "paper": paper, "paper_outside": outside}


def frame_morphology(vertices, faces, ellipsoid, face_tension=None, *, axis=COMPRESSION_AXIS,
                     scales=DEFAULT_SCALES, n_bands=N_BANDS) -> dict:
    """The morphology of one snapshot about its fitted ``ellipsoid`` (center, axes, rotation): the scalars of
    :meth:`.morphology.Morphology.summary`, ``euler`` (per DEFAULT_LEVELS), ``pattern`` (the class), and the
    wrinkle location (``energy_fraction``, ``enrichment``, ``band_tension`` per band, equator first;
    ``polar_enrichment``; ``tension_correlation``)."""
    v = np.asarray(vertices, float)
    f = np.asarray(faces)
    x, _ = _vertex_field(v, f, wrinkle_amplitude(v, f, ellipsoid, at="vertices"))
    lam = characteristic_degree(v, f, x)[1]
    shared = HeatSmoother(v, f, lam)  # scale 1.0 of the crest order and the energy density: the same smoother
    m = morphology_metrics(v, f, x, scales=scales, smoothers={1.0: shared} if 1.0 in scales else None)
    loc = wrinkle_location(v, f, x, axis, face_tension, n_bands=n_bands, smoothing=lam, smoother=shared)
    out = {**m.summary(), "euler": np.asarray(m.euler, float), "pattern": classify_features(m),
           "energy_fraction": loc.energy_fraction, "enrichment": loc.enrichment,
           "band_tension": loc.tension_mean if loc.tension_mean is not None else np.full(n_bands, np.nan),
           "polar_enrichment": loc.polar_enrichment, "tension_correlation": loc.correlation}
    return out


def morphology_variables(results, time, frames, scales=DEFAULT_SCALES, n_bands=N_BANDS) -> tuple[dict, dict]:
    """(data variables, coordinates) of the morphology for an xarray Dataset, on the dimension ``morph_time``:
    ``results`` the :func:`frame_morphology` dicts of ``frames["index"]`` in order."""
    idx = frames["index"]

    def var(dims, data, units, long_name, **extra):
        return (dims, data, {"units": units, "long_name": long_name, **extra})

    col = {k: np.array([r[k] for r in results], float) for k in results[0] if k not in ("pattern",)} if results \
        else {}
    empty = np.zeros(0)
    get = col.get
    data = {
        "l_c": var("morph_time", get("l_c", empty), "1", "characteristic degree of A_p (Rayleigh quotient)"),
        "wavelength": var("morph_time", get("wavelength", empty), "R",
                          "wrinkle wavelength 2 pi R / sqrt(l_c (l_c + 1))"),
        "height_rms": var("morph_time", get("rms", empty), "R", "rms of A_p about the fitted ellipsoid"),
        "ec_asymmetry": var("morph_time", get("ec_asymmetry", empty), "1",
                            "up-down asymmetry of the Euler curve of A_p (hexagons up > 0, down < 0)"),
        "low_degree_fraction": var("morph_time", get("low_degree_fraction", empty), "1",
                                   "share of the A_p variance in degrees l <= 6 (lobes and waist: peanut)"),
        "crest_alignment": var("morph_time", get("crest_alignment", empty), "1",
                               "crest alignment P: 1 ripples, ~cos 2 alpha herringbone, ~0 labyrinth"),
        "euler": var(("morph_time", "level"), np.array([r["euler"] for r in results]).reshape(len(results), -1),
                     "1", "Euler characteristic of the excursion set {A_p >= u rms}"),
        "anisotropy": var(("morph_time", "scale"), np.array([[r[f"anisotropy_{s:g}"] for s in scales]
                                                            for r in results]).reshape(len(results), -1),
                          "1", "structure-tensor coherence a_2 of the crests at the scale"),
        "defect_density": var(("morph_time", "scale"), np.array([[r[f"defect_density_{s:g}"] for s in scales]
                                                                for r in results]).reshape(len(results), -1),
                              "1", "crest defects per wavelength^2 at the scale"),
        "energy_fraction": var(("morph_time", "band"), np.array([r["energy_fraction"] for r in results])
                               .reshape(len(results), -1), "1", "share of the wrinkle energy in the latitude band"),
        "enrichment": var(("morph_time", "band"), np.array([r["enrichment"] for r in results])
                          .reshape(len(results), -1), "1", "energy share / area share of the band (1: uniform)"),
        "band_tension": var(("morph_time", "band"), np.array([r["band_tension"] for r in results])
                            .reshape(len(results), -1), "kappa R-2", "area-weighted mean local tension of the band"),
        "polar_enrichment": var("morph_time", get("polar_enrichment", empty), "1",
                                "enrichment of the two polar caps about the compressional axis x"),
        "tension_correlation": var("morph_time", get("tension_correlation", empty), "1",
                                   "area-weighted correlation of the wrinkle energy with the local tension"),
        "pattern": var("morph_time", np.array([CLASSES.index(r["pattern"]) for r in results], np.int8), "1",
                       "wrinkle pattern class (analysis.pattern_class; thresholds from synthetic fields only)",
                       flag_values=np.arange(len(CLASSES), dtype=np.int8), flag_meanings=" ".join(CLASSES)),
        "is_t_star": var("morph_time", (idx == frames["t_star"]).astype(np.int8), "1",
                         "1 at t_* (argmin Delta_2 over time >= 0)"),
        "paper_time": var("morph_time", np.array([next((t for t, i in frames["paper"].items() if i == k), np.nan)
                                                  for k in idx], float), "1",
                          "the paper's snapshot time (Figs. 6-8) this frame stands for, NaN if none"),
    }
    edges = np.linspace(0.0, 1.0, n_bands + 1)
    coords = {"morph_time": ("morph_time", np.asarray(time, float)[idx],
                             {"units": "1", "long_name": "gamma_dot (t - t0) of the classified frames"}),
              "level": ("level", np.asarray(DEFAULT_LEVELS, float),
                        {"units": "1", "long_name": "level u, in rms of A_p"}),
              "scale": ("scale", np.asarray(scales, float), {"units": "1",
                                                                       "long_name": "crest smoothing, in wavelengths"}),
              "band": ("band", 0.5 * (edges[:-1] + edges[1:]),
                       {"units": "1", "long_name": "centre of the band in |cos| of the latitude about x "
                                                   "(0 equator, 1 poles)"})}
    return data, coords

