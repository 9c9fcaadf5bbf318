"""Spherical-harmonic spectra of a trajectory (Sec. V: eqs. 30-32, t_*, l_*, A_p-bar), one snapshot at a time with
:func:`vesicle_core.analysis.shape.analyze_snapshot`, as an xarray Dataset.

Spectra layout: see :func:`spectra_from_trajectory`. Complex coefficients are stored as real and imaginary parts;
entries with |m| > l are NaN. The trajectory format it reads is in :mod:`vesicle_core.data.datasets`.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import xarray as xr

from ..data.datasets import _connectivity, cf_attrs, netcdf_safe_attrs, validate_trajectory
from ..errors import check_range
from ..geometry import surface as Sf
from ..geometry import ylm as Yl
from . import harmonics as H
from . import mesh_bias as MB
from . import shape

__all__ = ["DEFAULT_LMAX_CAP", "spectra_from_trajectory"]

DEFAULT_LMAX_CAP = 64


def _var(dims, data, units, long_name, **extra):
    return (dims, data, {"units": units, "long_name": long_name, **extra})


def _delta_from(traj, vertices, faces, delta):
    if delta is not None:
        return float(check_range("delta", delta, 0.0, None, lo_open=True)), "argument"
    d = traj.attrs.get("delta")
    try:
        d = float(np.asarray(d).ravel()[0])
    except (TypeError, ValueError, IndexError):
        d = float("nan")
    if math.isfinite(d) and d > 0:
        return d, "trajectory attribute delta"
    q = H.quadrature(vertices, faces)
    return float(q.areas.sum() / q.R**2 - 4.0 * math.pi), "first snapshot's meshed excess area"


def _read_snapshots(traj, stride, threshold):
    """The analysed snapshots: validate the trajectory and the arguments, keep every ``stride``-th frame.
    -> (the strided Dataset, the faces, the stride as an int)."""
    validate_trajectory(traj)
    stride = int(check_range("stride", stride, 1, None, integer=True))
    check_range("threshold", threshold, 0.0, None)
    return traj.isel(time=slice(None, None, stride)), _connectivity(traj, "trajectory"), stride


def _vertices_at(sub, k):
    """The vertices of snapshot ``k`` as an (n, 3) float array."""
    return np.stack([np.asarray(sub[c].isel(time=k).values, dtype=float) for c in ("node_x", "node_y", "node_z")],
                    axis=1)


def _choose_l_max(l_max, vertices, faces):
    """l_max of the expansion (default: what the mesh resolves, capped at DEFAULT_LMAX_CAP); warns
    ResolutionWarning above what it resolves. -> (l_max, the resolvable l_max)."""
    l_res = Sf.resolvable_l_max(vertices, faces)
    if l_max is None:
        l_max = max(2, min(DEFAULT_LMAX_CAP, l_res))
    l_max = int(check_range("l_max", l_max, 2, 1000, integer=True))
    if l_max > l_res:
        # stacklevel 3: the warning points at the caller of spectra_from_trajectory
        warnings.warn(
            f"l_max = {l_max} exceeds what this mesh resolves (pi / mean angular edge = {l_res}); "
            "modes above it are aliased mesh noise", H.ResolutionWarning, stacklevel=3)
    return l_max, l_res


def _map_grid(map_shape):
    """Cell-centred (theta, phi) grid of the A_p maps: (theta_g, phi_g, TH, PH), or None without maps."""
    if map_shape is None:
        return None
    n_th, n_ph = (int(check_range("map_shape", n, 1, 100_000, integer=True)) for n in map_shape)
    theta_g = (np.arange(n_th) + 0.5) * math.pi / n_th
    phi_g = -math.pi + (np.arange(n_ph) + 0.5) * 2.0 * math.pi / n_ph
    TH, PH = np.meshgrid(theta_g, phi_g, indexing="ij")
    return theta_g, phi_g, TH, PH


def _tension_stats(ft, areas):
    """Area-weighted mean and standard deviation of the local (per-face) tension ``ft``."""
    mean = float((ft * areas).sum() / areas.sum())
    return mean, math.sqrt(max(float(((ft - mean) ** 2 * areas).sum() / areas.sum()), 0.0))


def _analyse_snapshots(sub, faces, v0, l_max, delta, grid, progress, **harmonics_kw):
    """Sec. V on every snapshot of ``sub`` (:func:`shape.analyze_snapshot`: u_lm of eq. 30, u~_lm of eq. 32,
    l_* of eq. 31 per snapshot, A_p-bar, the ellipsoid) plus the local-tension statistics and the A_p maps.
    -> dict of arrays with a leading time axis (entries with |m| > l not yet masked)."""
    nt = sub.sizes["time"]
    L, M = l_max + 1, 2 * l_max + 1
    out = {"u": np.empty((nt, L, M), complex), "u_tilde": np.empty((nt, L, M), complex),
           **{k: np.empty(nt) for k in ("A_p_bar", "ft_mean", "ft_std", "R_eq", "Delta_mesh", "l_star_t")},
           "l_max_nontrivial_t": np.empty(nt, dtype=np.int32),
           "axes": np.empty((nt, 3)), "center": np.empty((nt, 3)), "rotation": np.empty((nt, 3, 3)),
           "centroid": np.empty((nt, 3)),
           "maps": np.empty((nt, grid[0].size, grid[1].size)) if grid is not None else None}
    it = range(nt)
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(it, desc="spectra", unit="snapshot")
    for k in it:
        v = v0 if k == 0 else _vertices_at(sub, k)
        r = shape.analyze_snapshot(v, faces, l_max, delta=delta, warn=False, **harmonics_kw)
        out["u"][k], out["u_tilde"][k] = r["u"], r["u_tilde"]
        out["l_max_nontrivial_t"][k] = r["l_max_nontrivial"]
        out["l_star_t"][k] = r["l_star"]
        out["A_p_bar"][k] = r["A_p_bar"]
        out["R_eq"][k] = r["R"]
        out["Delta_mesh"][k] = r["delta_mesh"]
        ft = np.asarray(sub["face_tension"].isel(time=k).values, dtype=float)
        out["ft_mean"][k], out["ft_std"][k] = _tension_stats(ft, r["areas"])
        out["center"][k], out["axes"][k], out["rotation"][k] = r["ellipsoid"]
        out["centroid"][k] = r["center"]
        if grid is not None:
            out["maps"][k] = r["R"] * Yl.synthesize(out["u_tilde"][k], grid[2], grid[3])
    return out


def _mask_and_sum(snap, l_max):
    """Set the entries with |m| > l to NaN and add Delta_l and Delta~_l (sum_m |u_lm|^2, eqs. 30 and 32)."""
    l = np.arange(l_max + 1)
    m = np.arange(-l_max, l_max + 1)
    invalid = np.abs(m)[None, :] > l[:, None]
    for arr in (snap["u"], snap["u_tilde"]):
        arr[:, invalid] = np.nan + 1j * np.nan
    snap["Delta_l"] = H.delta_l(snap["u"])
    snap["Delta_tilde_l"] = H.delta_l(snap["u_tilde"])


def _at_t_star(sub, faces, time, snap):
    """The scalars at t_* = argmin_{time >= 0} Delta_2 (Sec. V.A): t_star, l_star (eq. 31), l_max_nontrivial,
    l_peak and the mesh-bias measures there (NaN / -1 when no analysed snapshot has time >= 0)."""
    D, lmn = snap["Delta_l"], snap["l_max_nontrivial_t"]
    i_star = H.t_star_index(time, D[:, 2])
    out = {"t_star": float(time[i_star]) if i_star >= 0 else float("nan"),
           "l_star": float(snap["l_star_t"][i_star]) if i_star >= 0 else float("nan"),
           "l_max_nontrivial": int(lmn[i_star]) if i_star >= 0 else -1}
    out.update(_between_frames(time, D[:, 2], snap["l_star_t"], out))
    lmn_star = out["l_max_nontrivial"]
    out["l_peak"] = H.characteristic_l(D[i_star], lmn_star, method="peak") if lmn_star >= 3 else float("nan")
    out["bias"] = {"defect_amplitude_ratio": math.nan, "icosahedral_amplitude_ratio": math.nan,
                   "icosahedral_power_ratio": math.nan, "n_defects": -1}
    if i_star >= 0:
        ellipsoid = (snap["center"][i_star], snap["axes"][i_star], snap["rotation"][i_star])
        out["bias"] = MB.mesh_bias(_vertices_at(sub, i_star), faces, ellipsoid, snap["Delta_tilde_l"][i_star])
    return out


def _between_frames(time, D2, l_star_t, frame):
    """t_* between the frames (:func:`harmonics.t_star_between_frames`) and l_* there: l_*(t) of eq. (31) at every
    frame, interpolated by the same parabola through the three frames. l_*(t), not the spectrum Delta_l(t): eq. (31)
    is then applied exactly as at a frame, with that frame's l_max_nontrivial, instead of on an interpolated
    spectrum whose l_max (an integer that jumps between frames) would have to be chosen. Where there is nothing to
    fit (the minimum at an end of the record) or a neighbour has no l_* (no mode above the threshold), the frame
    values. -> t_star_fit, l_star_fit, t_star_fit_method."""
    t_fit, idx, w = H.t_star_between_frames(time, D2)
    l_fit = float(np.dot(w, l_star_t[list(idx)])) if idx else math.nan
    if len(idx) == 3 and math.isfinite(l_fit):
        return {"t_star_fit": t_fit, "l_star_fit": l_fit, "t_star_fit_method": "quadratic"}
    method = "frame (minimum at an end of the record)" if len(idx) == 1 else "frame (no l_* at a neighbour)"
    return {"t_star_fit": frame["t_star"], "l_star_fit": frame["l_star"],
            "t_star_fit_method": method if idx else "none"}


def _coords(sub, time, l_max, grid):
    """Coordinates of the spectra: time, [t_tau], l, m, axis, [theta, phi]."""
    coords = {
        "time": ("time", time, dict(sub["time"].attrs) or {"units": "1", "long_name": "gamma_dot (t - t_reverse)"}),
        "l": ("l", np.arange(l_max + 1), {"units": "1", "long_name": "spherical-harmonic degree l"}),
        "m": ("m", np.arange(-l_max, l_max + 1), {"units": "1", "long_name": "spherical-harmonic order m"}),
        "axis": ("axis", np.array(["x", "y", "z"]), {"long_name": "Cartesian axis"}),
    }
    if "t_tau" in sub.coords or "t_tau" in sub.variables:
        coords["t_tau"] = ("time", np.asarray(sub["t_tau"].values, dtype=float),
                           dict(sub["t_tau"].attrs) or {"units": "tau", "long_name": "time in tau = mu R^3 / kappa"})
    if grid is not None:
        coords["theta"] = ("theta", grid[0], {"units": "rad", "long_name": "polar angle about the vesicle centre"})
        coords["phi"] = ("phi", grid[1], {"units": "rad", "long_name": "azimuth about the vesicle centre"})
    return coords


def _spectral_vars(sub, snap, star, threshold):
    """The spectra proper: u_lm (eq. 30), u~_lm (eq. 32), their Delta_l, the tensions, A_p-bar and l_* (eq. 31)
    per snapshot and at t_*, with the mesh-bias measures at t_*."""
    u, ut, lmn = snap["u"], snap["u_tilde"], snap["l_max_nontrivial_t"]
    tl, tlm = ("time", "l"), ("time", "l", "m")
    bias = star["bias"]
    return {
        "u_real": _var(tlm, u.real, "1", "real part of the scaled amplitude u_lm, eq. (30); l < 2 unscaled"),
        "u_imag": _var(tlm, u.imag, "1", "imaginary part of the scaled amplitude u_lm, eq. (30); l < 2 unscaled"),
        "Delta_l": _var(tl, snap["Delta_l"], "1", "Delta_l = sum_m |u_lm|^2"),
        "u_tilde_real": _var(tlm, ut.real, "1", "real part of the wrinkle-amplitude coefficient u~_lm, eq. (32)"),
        "u_tilde_imag": _var(tlm, ut.imag, "1", "imaginary part of the wrinkle-amplitude coefficient u~_lm, eq. (32)"),
        "Delta_tilde_l": _var(tl, snap["Delta_tilde_l"], "1", "Delta~_l = sum_m |u~_lm|^2"),
        "sigma": _var(("time",), np.asarray(sub["tension"].values, dtype=float), "kappa R-2",
                      "global surface tension (from the trajectory)"),
        "face_tension_mean": _var(("time",), snap["ft_mean"], "kappa R-2", "area-weighted mean of the local tension"),
        "face_tension_std": _var(("time",), snap["ft_std"], "kappa R-2",
                                 "area-weighted standard deviation of the local tension"),
        "A_p_bar": _var(("time",), snap["A_p_bar"], "R2",
                        "mean square wrinkle amplitude (1/A) sum_i A_p,i^2 A_i, Sec. V.C"),
        "l_max_nontrivial_t": _var(("time",), lmn, "1", f"largest l with some |u_lm| > {threshold:g} (-1: none)"),
        "l_star_t": _var(("time",), snap["l_star_t"], "1",
                         "characteristic wrinkle mode l_*, eq. (31), up to l_max_nontrivial_t"),
        "t_star": _var((), star["t_star"], "1",
                       "t_*: time >= 0 at which Delta_2 is smallest (gamma_dot (t - t_reverse))"),
        "l_star": _var((), star["l_star"], "1", "l_* of eq. (31) at t_*"),
        "t_star_fit": _var((), star["t_star_fit"], "1", "t_* between the frames: vertex of the parabola through the "
                           "sampled minimum of Delta_2 and its two neighbours (gamma_dot (t - t_reverse))",
                           comment=f"method: {star['t_star_fit_method']}"),
        "l_star_fit": _var((), star["l_star_fit"], "1", "l_* of eq. (31) at t_star_fit: l_star_t interpolated by "
                           "the same parabola", comment=f"method: {star['t_star_fit_method']}"),
        "l_peak": _var((), star["l_peak"], "1", "dominant wrinkle mode argmax_{3<=l<=l_max} Delta_l at t_* (Sec. V.A)"),
        "defect_amplitude_ratio": _var((), bias["defect_amplitude_ratio"], "1",
                                       "rms A_p at mesh defects (valence != 6) / rms A_p, at t_* (mesh bias)"),
        "icosahedral_amplitude_ratio": _var((), bias["icosahedral_amplitude_ratio"], "1",
                                            "rms A_p at the 12 icosahedron directions / rms A_p, at t_* (mesh bias)"),
        "icosahedral_power_ratio": _var((), bias["icosahedral_power_ratio"], "1",
                                        "mean Delta~_l at l = 6, 10, 12 / mean at l = 8, 14, at t_* (mesh bias)"),
        "l_max_nontrivial": _var((), np.int32(star["l_max_nontrivial"]), "1",
                                 f"largest l with some |u_lm| > {threshold:g} at t_*"),
    }


def _geometry_vars(snap):
    """The geometry of each snapshot: the least-squares ellipsoid, the expansion centre and radius, the meshed
    excess area, and the A_p maps when they were synthesised."""
    ta = ("time", "axis")
    data = {
        "ellipsoid_axes": _var(ta, snap["axes"], "R", "semi-axes of the least-squares ellipsoid, ordered by the lab "
                               "axis each is closest to"),
        "ellipsoid_center": _var(ta, snap["center"], "R", "centre of the least-squares ellipsoid"),
        "ellipsoid_rotation": (("time", "axis", "principal"), snap["rotation"], {
            "units": "1", "long_name": "columns: unit directions of the ellipsoid semi-axes (lab components)"}),
        "centroid": _var(ta, snap["centroid"], "R", "volume centroid of the vesicle (expansion centre X_C)"),
        "R_eq": _var(("time",), snap["R_eq"], "R", "equivalent radius from the enclosed volume (expansion radius)"),
        "Delta_mesh": _var(("time",), snap["Delta_mesh"], "1", "meshed excess area A / R_eq^2 - 4 pi"),
    }
    if snap["maps"] is not None:
        data["A_p_map"] = _var(("time", "theta", "phi"), snap["maps"], "R",
                               "wrinkle amplitude A_p(theta, phi) synthesised from u~_lm up to l_max")
    return data


def _spectra_attrs(traj, command, **analysis):
    """The trajectory's attributes (less its CF header), then the CF attributes and the analysis parameters;
    the trajectory's history is kept below the new entry."""
    attrs = netcdf_safe_attrs({k: v for k, v in traj.attrs.items()
                               if k not in ("Conventions", "title", "source", "history")})
    cf = cf_attrs("spherical-harmonic spectra of a vesicle trajectory (Sec. V, eqs. 30-32)", command=command,
                  **analysis, t_star_definition="argmin of Delta_2 over time >= 0",
                  t_star_fit_definition="vertex of the parabola through the sampled minimum of Delta_2 and its "
                  "two neighbours; l_star_fit: l_star_t interpolated there by the same parabola")
    if "history" in traj.attrs:
        cf["history"] = f"{cf['history']}\n{traj.attrs['history']}"
    attrs.update(cf)
    return attrs


def spectra_from_trajectory(
    traj: xr.Dataset, l_max: int | None = None, stride: int = 1, progress: bool = False, *,
    rule: str = "pn", weights: str = "solid_angle", threshold: float = H.NONTRIVIAL_THRESHOLD,
    fit: str = "quadrature", delta: float | None = None, map_shape: tuple[int, int] | None = None,
    command: str | None = None,
) -> xr.Dataset:
    """Spherical-harmonic analysis (Sec. V) of every ``stride``-th snapshot of a trajectory.

    l_max: default the largest the mesh resolves (:func:`surface.resolvable_l_max`), capped at 64; a larger
    value warns ResolutionWarning. delta: Delta of the eq. (30) scale factor (default: the trajectory's ``delta``
    attribute, else the first snapshot's meshed excess area). rule / weights: quadrature (harmonics docstring).
    fit: ``quadrature`` (eq. 30 as printed) or ``least_squares`` (removes the quadrature's aliasing floor on
    irregular meshes at ~4x the time; :func:`harmonics.fit_coefficients`). threshold: |u_lm| above which a mode
    counts as nontrivial (l_max of Sec. V.A). map_shape (n_theta, n_phi):
    also store A_p(theta, phi) maps synthesised from u~_lm on a cell-centred grid.

    Result layout -- coords: time, t_tau (if the trajectory has it), l (0..l_max), m (-l_max..l_max), axis (x, y, z),
    [theta, phi]; data (per-variable units and long_name):
      u_real, u_imag (time, l, m)       scaled amplitudes u_lm of eq. (30); l < 2 unscaled; NaN for |m| > l
      Delta_l (time, l)                 sum_m |u_lm|^2
      u_tilde_real, u_tilde_imag, Delta_tilde_l   eq. (32) spectrum of A_p and its Delta~_l
      sigma (time)                      global tension, copied from the trajectory
      face_tension_mean, face_tension_std (time)  area-weighted statistics of the local tension
      A_p_bar (time)                    (1/A) sum A_p^2 A_i [R^2]
      l_max_nontrivial_t, l_star_t (time)  largest l with |u_lm| > threshold, and eq. (31) up to it
      t_star, l_star, l_max_nontrivial  scalars at t_* = argmin_{time >= 0} Delta_2 (NaN / -1 if no such time)
      t_star_fit, l_star_fit            t_* between the frames (parabola through the sampled minimum and its two
                                        neighbours) and l_star_t interpolated there; the frame values at an end
      ellipsoid_axes, ellipsoid_center (time, axis), ellipsoid_rotation (time, axis, principal)
      centroid (time, axis), R_eq (time), Delta_mesh (time)   geometry of each snapshot
      [A_p_map (time, theta, phi)]
    attrs: the trajectory's attributes, then the CF attributes and the analysis parameters (l_max, stride, rule,
    weights, fit, threshold, delta_used, delta_source, resolvable_l_max). t_* is taken over the analysed (strided)
    snapshots only.
    """
    sub, faces, stride = _read_snapshots(traj, stride, threshold)
    v0 = _vertices_at(sub, 0)
    l_max, l_res = _choose_l_max(l_max, v0, faces)
    delta_used, delta_source = _delta_from(traj, v0, faces, delta)
    grid = _map_grid(map_shape)
    snap = _analyse_snapshots(sub, faces, v0, l_max, delta_used, grid, progress, rule=rule, weights=weights, fit=fit,
                              threshold=threshold)
    _mask_and_sum(snap, l_max)
    time = np.asarray(sub["time"].values, dtype=float)
    star = _at_t_star(sub, faces, time, snap)
    data = {**_spectral_vars(sub, snap, star, threshold), **_geometry_vars(snap)}
    attrs = _spectra_attrs(traj, command, l_max=l_max, stride=stride, rule=rule, weights=weights, fit=fit,
                           threshold=float(threshold), delta_used=delta_used, delta_source=delta_source,
                           resolvable_l_max=l_res, n_snapshots=sub.sizes["time"])
    return xr.Dataset(data, coords=_coords(sub, time, l_max, grid), attrs=attrs)
