"""``vesicle microscope``: virtual phase-contrast microscopy of a trajectory -> microscope.nc.

Registered in :mod:`vesicle_core.cli`; ``add_microscope(sub)`` adds the subparser, ``add_pattern_claims(sub)`` the
report of the paper's three pattern claims (docs/validation_morphology.md).
"""

from __future__ import annotations

import sys

from ..analysis.micrograph import Optics
from .args import finite_float, int_in, positive_float


def add_microscope(sub):
    p = sub.add_parser("microscope", help="what a phase-contrast microscope sees of a trajectory: outlines in the "
                                          "focal plane, their k_*, crests and spectra -> microscope.nc")
    p.add_argument("trajectory", help="trajectory.nc written by 'vesicle run'")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    p.add_argument("--spectra", default=None, help="spectra.nc of the same trajectory: reuse its fitted ellipsoids")
    p.add_argument("--stride", type=int_in("--stride", 1, 10**6), default=1, help="analyse every k-th frame")
    p.add_argument("--offset", type=float, default=0.0,
                   help="focal plane's distance from the vesicle's centre along --normal, in R, within [-1.5, 1.5] "
                        "(default 0: the flow's plane)")
    p.add_argument("--normal", type=float, nargs=3, default=(0.0, 0.0, 1.0), metavar=("NX", "NY", "NZ"),
                   help="normal of the focal plane (default 0 0 1: the optical axis along z)")
    p.add_argument("--radius-um", type=positive_float("--radius-um"), default=None,
                   help="R in micrometres (default: 16.71 for Delta < 0.5, else 18, the radii of Sec. V)")
    p.add_argument("--na", type=positive_float("--na"), default=Optics.numerical_aperture,
                   help=f"numerical aperture (default {Optics.numerical_aperture})")
    p.add_argument("--magnification", type=positive_float("--magnification"), default=Optics.magnification,
                   help=f"objective magnification (default {Optics.magnification:g})")
    p.add_argument("--camera-pixel-um", type=positive_float("--camera-pixel-um"), default=Optics.camera_pixel_um,
                   help=f"camera pixel in micrometres (default {Optics.camera_pixel_um})")
    p.add_argument("--wavelength-um", type=positive_float("--wavelength-um"), default=Optics.wavelength_um,
                   help=f"wavelength in micrometres (default {Optics.wavelength_um})")
    p.add_argument("--n-theta", type=int_in("--n-theta", 16, 65536), default=512,
                   help="rays per outline (even; default 512)")
    p.add_argument("--n-images", type=int_in("--n-images", 0, 1000), default=6,
                   help="images kept in the file, evenly spread over t >= 0 (default 6)")
    p.add_argument("--image-times", type=finite_float("--image-times"), nargs="+", default=None,
                   help="keep the images of the frames nearest these gamma_dot (t - t0) instead (e.g. Fig. 6's)")
    p.add_argument("--morphology-stride", type=int_in("--morphology-stride", 0, 10**6), default=5,
                   help="measure the 3D wrinkle morphology and its pattern class at every k-th analysed frame of the "
                        "reversed flow, plus t_* and the paper's snapshot times (default 5; 0: no morphology)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_cmd_microscope)


def _cmd_microscope(a):
    from ..analysis.micrograph import Optics
    from ..analysis.microscope import microscope_from_trajectory
    from ..data.datasets import open_trajectory, read_dataset, write_dataset

    optics = Optics(numerical_aperture=a.na, magnification=a.magnification, camera_pixel_um=a.camera_pixel_um,
                    wavelength_um=a.wavelength_um)
    spectra = read_dataset(a.spectra) if a.spectra else None
    with open_trajectory(a.trajectory, require_complete=True) as traj:
        ds = microscope_from_trajectory(traj, spectra=spectra, optics=optics, radius_um=a.radius_um,
                                        offset=a.offset, normal=a.normal, stride=a.stride, n_theta=a.n_theta,
                                        n_images=a.n_images, image_times=a.image_times,
                                        morphology_stride=a.morphology_stride or None, progress=not a.quiet,
                                        command=" ".join(sys.argv))
    write_dataset(ds, a.output)
    own_s = float(ds.attrs["microscope_wall_time_s"]) + float(ds.attrs["morphology_wall_time_s"])
    at_star = ds.attrs.get("pattern_at_t_star")
    print(f"wrote {a.output}: {ds.sizes['time']} frames, max k_* {float(ds.attrs['k_star_max']):.3g}, "
          f"outline vs section {float(ds.outline_mismatch.median()):.3f} px rms (median), "
          + (f"pattern at t_* {at_star}, " if at_star else "")
          + f"{own_s:.1f} s ({100 * float(ds.attrs['cost_fraction']):.1f}% of the run's "
          f"{float(ds.attrs.get('wall_time_s', float('nan'))):.0f} s)")
    return 0


def add_pattern_claims(sub):
    p = sub.add_parser("pattern-claims", help="the paper's three wrinkle-pattern claims decided from the runs' "
                                              "microscope.nc -> a Markdown section (docs/validation_morphology.md)")
    p.add_argument("--case", nargs=3, action="append", required=True, metavar=("CASE_ID", "MICROSCOPE", "SPECTRA"),
                   help="a case: its id, microscope.nc and spectra.nc (repeat per case)")
    p.add_argument("--missing", nargs="*", default=[], help="the paper's cases not produced yet (named in the text)")
    p.add_argument("-o", "--output", required=True, help="Markdown file to write")
    p.set_defaults(func=_cmd_pattern_claims)


def _cmd_pattern_claims(a):
    from ..validation.report import write_morphology_claims

    out = write_morphology_claims([tuple(c) for c in a.case], a.output, a.missing)
    print(f"wrote {out}: {len(a.case)} cases")
    return 0
