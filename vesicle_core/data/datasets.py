"""xarray Datasets of the analysis: CF attributes, atomic netCDF writing and validated reading.

Trajectory format (written by the solver, ``trajectory.nc``)
    dims     time, n_node, n_face, n_vertex_per_face (= 3)
    coords   time (time) = gamma_dot (t - t_reverse), negative before the flow reversal; t_tau (time) in tau
    vars     node_x, node_y, node_z (time, n_node) [R]; face_node_connectivity (n_face, 3) int;
             face_tension (time, n_face) [kappa/R^2]; tension (time) [kappa/R^2]; area, volume, bending_energy,
             tension_energy, area_drift, volume_drift (time); since the format became UGRID (a finished run's
             file): the mesh topology ``mesh`` and node_lon, node_lat (n_node), the vertex directions of the
             first frame seen from its centroid, the mesh's node coordinates (docs/reference/datasets.md)
    units    in the file, a solver unit X is written as units "1" with nondimensional_units "X"
             (:func:`vesicle_core.model.units.cf_unit_attrs`); the brackets above give X
    attrs    chi, S, delta (meshed excess area), Re, N, L, dt, Lambda, mesh_family, mesh_level, backend, ...;
             complete = 1 when the run finished

The spectra of a trajectory (Sec. V) are computed in :mod:`vesicle_core.analysis.spectra`.
"""

from __future__ import annotations

import json
import shlex
import sys
import warnings
from datetime import UTC, datetime
from numbers import Number
from pathlib import Path

import numpy as np
import xarray as xr

from .. import __version__
from ..errors import ConfigError, VesicleError, check_range

__all__ = [
    "DatasetError",
    "MissingDataError",
    "IncompleteRunWarning",
    "REQUIRED_VARIABLES",
    "cf_attrs",
    "netcdf_safe_attrs",
    "write_dataset",
    "read_dataset",
    "validate_trajectory",
    "open_trajectory",
]

COMPRESS_MIN_SIZE = 10_000  # variables with more elements than this are written with zlib (complevel 4)

TRAJECTORY_VARIABLES = (
    "node_x", "node_y", "node_z", "face_node_connectivity", "face_tension", "tension",
    "area", "volume", "bending_energy", "tension_energy", "area_drift", "volume_drift",
)
SPECTRA_VARIABLES = (
    "u_real", "u_imag", "Delta_l", "sigma", "face_tension_mean", "face_tension_std", "A_p_bar",
    "u_tilde_real", "u_tilde_imag", "Delta_tilde_l", "l_star_t", "t_star", "l_star", "l_max_nontrivial",
    "ellipsoid_axes",
)
#: Variables each dataset kind must hold; other modules may add their kinds here.
REQUIRED_VARIABLES: dict[str, tuple[str, ...]] = {
    "trajectory": TRAJECTORY_VARIABLES,
    "spectra": SPECTRA_VARIABLES,
    "mesh": ("node_x", "node_y", "node_z", "face_node_connectivity"),
}


class DatasetError(VesicleError, ValueError):
    """A file or Dataset is not a readable dataset of the expected kind (the message names the file)."""


class MissingDataError(DatasetError):
    """A dataset file does not exist, or lacks variables its kind requires."""


class IncompleteRunWarning(UserWarning):
    """The trajectory's run did not finish (attribute ``complete`` is not 1)."""


# --------------------------------------------------------------------------- attributes
def _attr_value(v):
    """One attribute value in a form netCDF4 can store (None -> "none", bool -> 0/1, paths -> str,
    numeric sequences -> arrays, anything else -> JSON or str)."""
    if v is None:
        return "none"
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, (str, bytes)):
        return v if isinstance(v, str) else v.decode()
    if isinstance(v, (np.integer, np.floating)):
        return v.item()
    if isinstance(v, Number):
        return v
    if isinstance(v, Path):
        return str(v)
    if isinstance(v, np.ndarray) and v.dtype.kind in "iuf" and v.ndim <= 1:
        return v
    if isinstance(v, (list, tuple, np.ndarray)):
        seq = list(v.tolist() if isinstance(v, np.ndarray) else v)
        if seq and all(isinstance(x, (Number, np.number)) and not isinstance(x, (bool, np.bool_)) for x in seq):
            return np.asarray(seq)
        if seq and all(isinstance(x, (bool, np.bool_)) for x in seq):
            return np.asarray(seq, dtype=np.int8)
        try:
            return json.dumps(seq, default=str)
        except (TypeError, ValueError):
            return str(seq)
    return str(v)


def netcdf_safe_attrs(attrs: dict, prefix: str = "") -> dict:
    """Flatten nested dicts (keys joined by '_') and convert every value with netCDF-safe rules."""
    out = {}
    for k, v in attrs.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(netcdf_safe_attrs(v, prefix=f"{key}_"))
        else:
            out[key] = _attr_value(v)
    return out


def cf_attrs(title: str, command: str | None = None, **params) -> dict:
    """Global attributes for a dataset: Conventions (CF-1.10), title, source (``vesicle_core <version>``),
    history (ISO-8601 UTC timestamp + the command that made it; default: this process's command line) and every
    run parameter, converted to netCDF-safe values (bool -> 0/1, None -> "none", nested dicts flattened)."""
    if command is None:
        command = shlex.join([Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python", *sys.argv[1:]])
    stamp = datetime.now(UTC).isoformat(timespec="seconds")
    attrs = {
        "Conventions": "CF-1.10",
        "title": str(title),
        "source": f"vesicle_core {__version__}",
        "history": f"{stamp} {command}",
    }
    for k, v in netcdf_safe_attrs(params).items():
        if k in attrs:
            raise ConfigError(f"parameter name {k!r} collides with a CF attribute")
        attrs[k] = v
    return attrs


# --------------------------------------------------------------------------- writing and reading
_KEEP_ENCODING = ("dtype", "_FillValue", "scale_factor", "add_offset", "units", "calendar")


def write_dataset(ds: xr.Dataset, path, complevel: int = 4) -> Path:
    """Write ``ds`` to netCDF4 atomically (temp file beside ``path``, then rename: an interrupted write never
    leaves a file under the final name). Variables with more than 10^4 elements are zlib-compressed
    (``complevel``, with shuffle); attributes are made netCDF-safe first, solver units become CF units
    (:func:`vesicle_core.model.units.cf_unit_attrs`) and the global attributes state the scales
    (:data:`vesicle_core.model.units.SCALE_ATTRS`). The values are written unchanged. Returns the path."""
    from ..io import atomic_to_netcdf
    from ..model.units import SCALE_ATTRS, cf_unit_attrs

    check_range("complevel", complevel, 0, 9, integer=True)
    path = Path(path)
    out = ds.copy(deep=False)
    out.attrs = {**netcdf_safe_attrs(ds.attrs), **{k: v for k, v in SCALE_ATTRS.items() if k not in ds.attrs}}
    encoding = {}
    for name, var in out.variables.items():
        out[name].attrs = netcdf_safe_attrs(cf_unit_attrs(var.attrs))
        if "units" in out[name].encoding and "units" in out[name].attrs:
            del out[name].encoding["units"]
        if var.size > COMPRESS_MIN_SIZE and var.dtype.kind in "iufb":
            enc = {k: v for k, v in var.encoding.items() if k in _KEEP_ENCODING}
            enc.update(zlib=True, complevel=int(complevel), shuffle=True)
            encoding[name] = enc
    atomic_to_netcdf(out, path, encoding=encoding)
    return path


def _check_required(ds, required, source, kind):
    missing = [v for v in required if v not in ds.variables]
    if missing:
        have = ", ".join(sorted(map(str, ds.data_vars))) or "nothing"
        raise MissingDataError(
            f"{source}: not a {kind} dataset: missing variable(s) {', '.join(missing)} (it holds: {have})"
        )


def _required_for(kind, required):
    if required is not None:
        return tuple(required)
    if kind is None:
        return ()
    if kind not in REQUIRED_VARIABLES:
        raise ConfigError(f"unknown dataset kind {kind!r}; known kinds: {', '.join(REQUIRED_VARIABLES)}")
    return REQUIRED_VARIABLES[kind]


def _open(path, kind):
    path = Path(path)
    if not path.exists():
        raise MissingDataError(f"{path}: file does not exist" + (f" (expected a {kind} dataset)" if kind else ""))
    if path.is_dir():
        raise DatasetError(f"{path}: is a directory, not a netCDF file")
    try:
        return xr.open_dataset(path, engine="netcdf4")
    except (OSError, ValueError, RuntimeError, KeyError, TypeError) as exc:
        raise DatasetError(f"{path}: not a readable netCDF file ({type(exc).__name__}: {exc})") from None


def read_dataset(path, kind: str | None = None, required=None) -> xr.Dataset:
    """Read a whole dataset into memory (the file is closed on return).

    kind: one of REQUIRED_VARIABLES ("trajectory", "spectra", "mesh"; None: no check) or ``required``, an explicit
    list of variable names. Raises MissingDataError (file missing, variables missing) or DatasetError (not
    netCDF), each naming the file and what is wrong.
    """
    req = _required_for(kind, required)
    ds = _open(path, kind)
    try:
        _check_required(ds, req, path, kind or "requested")
        if kind == "trajectory":
            validate_trajectory(ds, source=str(path))
        ds.load()
    finally:
        ds.close()
    return ds


def _connectivity(ds, source):
    fc = ds["face_node_connectivity"]
    vals = np.asarray(fc.values)
    if vals.dtype.kind == "f":
        if not np.all(np.isfinite(vals)) or not np.all(vals == np.round(vals)):
            raise DatasetError(f"{source}: face_node_connectivity must hold integer vertex indices")
    elif vals.dtype.kind not in "iu":
        raise DatasetError(f"{source}: face_node_connectivity has dtype {vals.dtype}, expected integers")
    faces = vals.astype(np.int64)
    start = int(fc.attrs.get("start_index", 0))
    return faces - start


def validate_trajectory(ds: xr.Dataset, source="dataset") -> None:
    """Raise MissingDataError / DatasetError unless ``ds`` follows the trajectory format (module docstring)."""
    _check_required(ds, TRAJECTORY_VARIABLES, source, "trajectory")
    if "time" not in ds.dims or "time" not in ds.coords:
        raise DatasetError(f"{source}: trajectory needs a 'time' dimension with a coordinate")
    if ds.sizes["time"] == 0:
        raise DatasetError(f"{source}: trajectory has no snapshots (time has length 0)")
    expect = {
        "node_x": ("time", "n_node"), "node_y": ("time", "n_node"), "node_z": ("time", "n_node"),
        "face_node_connectivity": ("n_face", "n_vertex_per_face"), "face_tension": ("time", "n_face"),
        "tension": ("time",), "area": ("time",), "volume": ("time",),
    }
    for name, dims in expect.items():
        if ds[name].dims != dims:
            raise DatasetError(f"{source}: {name} has dims {ds[name].dims}, expected {dims}")
    if ds.sizes["n_vertex_per_face"] != 3:
        raise DatasetError(f"{source}: n_vertex_per_face is {ds.sizes['n_vertex_per_face']}, expected 3 (triangles)")
    faces = _connectivity(ds, source)
    n_node = ds.sizes["n_node"]
    if faces.size == 0 or faces.min() < 0 or faces.max() >= n_node:
        raise DatasetError(f"{source}: face_node_connectivity indices must lie in [0, {n_node - 1}]")
    t = np.asarray(ds["time"].values, dtype=float)
    if np.any(np.diff(t) <= 0):
        raise DatasetError(f"{source}: time must be strictly increasing")


def _is_complete(value) -> bool:
    try:
        return float(np.asarray(value).ravel()[0]) == 1.0
    except (TypeError, ValueError, IndexError):
        return False


def open_trajectory(path, require_complete: bool = False) -> xr.Dataset:
    """Open a solver trajectory *lazily* (node positions are read per snapshot; close it, or use ``with``),
    after validating its format. Raises MissingDataError / DatasetError naming the file; an unfinished run
    (``complete`` != 1) raises DatasetError with ``require_complete`` and otherwise warns IncompleteRunWarning."""
    ds = _open(path, "trajectory")
    try:
        validate_trajectory(ds, source=str(path))
        complete = ds.attrs.get("complete", 0)
        if not _is_complete(complete):
            msg = f"{path}: the run did not finish (attribute complete = {complete!r})"
            if require_complete:
                raise DatasetError(msg)
            warnings.warn(msg, IncompleteRunWarning, stacklevel=2)
    except BaseException:
        ds.close()
        raise
    return ds
