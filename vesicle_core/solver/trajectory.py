"""What a run writes and reads back: the run directory's file names, the :class:`State` of the time loop and its
checkpoint, the trajectory writer and the failure diagnostic.

Run directory (``vesicle run -o DIR``)
    trajectory.partial.nc  output frames appended while the run goes (unlimited ``time`` dimension)
    trajectory.nc          the same, renamed by :meth:`TrajectoryWriter.finalize` only once the run is complete
                           (``complete = 1``, time coordinate gamma_dot (t - t_reverse); format in ``datasets.py``)
    checkpoint.nc          the State (and the fluid state at finite Re), rewritten atomically every
                           ``checkpoint_every`` steps; a rerun resumes from it and ends bit-identical
    failure.nc             positions and message of a run stopped by NumericalInstability

Frames written after the checkpoint a run resumes from are dropped on resume (:meth:`TrajectoryWriter._truncate`):
they are recomputed identically. A frame that cannot be written because another program holds the partial file
open stays in memory until the file is free; no checkpoint is written past a frame that is not on disk.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError, NumericalInstability
from ..geometry.mesh import FACE_FIELD_ATTRS, FACE_NODE_ATTRS, NODE_FIELD_ATTRS, ugrid_variables
from ..io import atomic_to_netcdf
from ..model.units import SCALE_ATTRS, cf_unit_attrs
from .step_limits import frame_variables

TRAJECTORY = "trajectory.nc"
PARTIAL = "trajectory.partial.nc"
CHECKPOINT = "checkpoint.nc"
FAILURE = "failure.nc"
#: how long the end of a run waits for a trajectory file that another program holds open
FINAL_WAIT_S = 600.0


@dataclass
class State:
    """The time loop's state, everything a checkpoint holds: positions, time, phase, the output bookkeeping and the
    scheme's own unknowns (global multiplier, cached mobility data, per-triangle tension)."""

    X: object  # (V, 3) on the run's array module
    t: float = 0.0  # tau
    step: int = 0
    phase: str = "stretch"  # "stretch" | "relax"
    t_reverse: float = math.nan  # tau, set at the reversal
    n_frames: int = 0
    next_output: int = 0  # step of the next output frame
    dt: float = 0.0
    shape_prev: tuple = ()  # second moments at the previous output (stationarity test)
    sigma_g: float = 0.0  # global tension multiplier of the projection scheme [kappa/R^2]
    w: object = None  # cached M grad(A) of the projection scheme, (V, 3)
    sigma: object = None  # per-triangle tension of the inextensible scheme, (F,)
    sigma_prev: object = None  # the one before (warm start by extrapolation)
    next_output_t: float = 0.0  # tau of the next frame (adaptive steps)
    dt_steps: tuple = ()  # lengths of the last two steps (tau), for the extrapolated warm start
    cg_iterations: list = None  # per step (inextensible)
    seed_l_max: int = -1  # highest l of the thermal seed put on at the reversal (-1: none)
    wall_s: float = 0.0  # wall time of the earlier calls of a resumed run (s)
    tension_rho: object = None  # tension_space harmonic: the measured area rate per l of the last refresh
    tension_rho_age: int = 0  # steps since that refresh
    strain_err: float = 0.0  # inextensible: the last step's linearisation strain (dt_strain), before any ALE motion
    dt_bending: float = 0.0  # inextensible: the bending limit re-measured during the run (tau; 0: the start's)
    bending_mode: object = None  # its stiffest mode (Arnoldi), (V, 3): the next measurement's start
    lipid_area: object = None  # mesh_ale shape: the lipid area each triangle carries, (F,) on the host (None: A0)
    tension_secant: object = None  # cg_precond secant: the BFGS model of the harmonic tension's rate operator, (K, K)
    tension_noise: object = None  # cg_precond secant, thermal: the last step's modelled noise response, (K,)
    limit_counts: list = None  # steps set by each of step_limits.LIMITS since the last frame
    limit_last: int = -1  # the limit that set the last step (index in step_limits.LIMITS; -1: no step yet)
    limit_dt: list = None  # the step each limit allowed for the last step (tau, NaN: not applied)
    dt_error: float = 0.0  # step_control error: the next step the error controller wants (tau; 0: none yet)


def save_checkpoint(path: Path, state: State, be, u_hat):
    import xarray as xr

    data = {"X": (("n_node", "xyz"), be.asnumpy(state.X))}
    if state.w is not None:
        data["w"] = (("n_node", "xyz"), be.asnumpy(state.w))
    for name in ("sigma", "sigma_prev"):
        if getattr(state, name) is not None:
            data[name] = (("n_face",), be.asnumpy(getattr(state, name)))
    if state.bending_mode is not None:
        data["bending_mode"] = (("n_node", "xyz"), be.asnumpy(state.bending_mode))
    if state.lipid_area is not None:
        data["lipid_area"] = (("n_face",), np.asarray(state.lipid_area, dtype=float))
    if state.tension_rho is not None:
        data["tension_rho"] = (("n_l",), np.asarray(state.tension_rho, dtype=float))
    if state.tension_secant is not None:
        data["tension_secant"] = (("n_coef", "n_coef_"), np.asarray(state.tension_secant, dtype=float))
    if state.tension_noise is not None:
        data["tension_noise"] = (("n_coef",), np.asarray(state.tension_noise, dtype=float))
    if state.cg_iterations:
        data["cg_iterations"] = (("n_step",), np.asarray(state.cg_iterations, dtype=np.int32))
    if u_hat is not None:
        dims = ("xyz", "kx", "ky", "kz")
        data["u_hat_re"] = (dims, u_hat.real)
        data["u_hat_im"] = (dims, u_hat.imag)
    attrs = {
        "t": state.t, "step": state.step, "phase": state.phase, "t_reverse": state.t_reverse,
        "n_frames": state.n_frames, "next_output": state.next_output, "dt": state.dt,
        "shape_prev": np.asarray(state.shape_prev, dtype=float), "sigma_g": state.sigma_g,
        "next_output_t": state.next_output_t, "seed_l_max": state.seed_l_max, "wall_s": state.wall_s,
        "tension_rho_age": state.tension_rho_age, "strain_err": state.strain_err, "dt_bending": state.dt_bending,
        "dt_error": state.dt_error,
    }
    if state.dt_steps:  # netCDF attributes cannot be empty
        attrs["dt_steps"] = np.asarray(state.dt_steps, dtype=float)
    attrs["limit_last"] = state.limit_last
    if state.limit_counts is not None:
        attrs["limit_counts"] = np.asarray(state.limit_counts, dtype=np.int64)
    if state.limit_dt is not None:
        attrs["limit_dt"] = np.asarray(state.limit_dt, dtype=float)
    atomic_to_netcdf(xr.Dataset(data, attrs=attrs), path)


def load_checkpoint(path: Path, xp):
    import xarray as xr

    try:
        with xr.open_dataset(path) as ds:
            ds.load()
    except (OSError, ValueError) as exc:
        raise ConfigError(f"checkpoint {path} is unreadable ({exc}); delete it to start the run afresh") from None
    a = ds.attrs
    st = State(
        X=xp.asarray(ds["X"].values), t=float(a["t"]), step=int(a["step"]), phase=str(a["phase"]),
        t_reverse=float(a["t_reverse"]), n_frames=int(a["n_frames"]), next_output=int(a["next_output"]),
        dt=float(a["dt"]), shape_prev=tuple(np.atleast_1d(a["shape_prev"]).tolist()), sigma_g=float(a["sigma_g"]),
        w=xp.asarray(ds["w"].values) if "w" in ds else None,
        sigma=xp.asarray(ds["sigma"].values) if "sigma" in ds else None,
        sigma_prev=xp.asarray(ds["sigma_prev"].values) if "sigma_prev" in ds else None,
        next_output_t=float(a.get("next_output_t", 0.0)), seed_l_max=int(a.get("seed_l_max", -1)),
        wall_s=float(a.get("wall_s", math.nan)),  # unknown for checkpoints written before it was recorded
        dt_steps=tuple(np.atleast_1d(a.get("dt_steps", np.zeros(0))).tolist()),
        cg_iterations=[int(v) for v in ds["cg_iterations"].values] if "cg_iterations" in ds else [],
        tension_rho=ds["tension_rho"].values.copy() if "tension_rho" in ds else None,
        tension_rho_age=int(a.get("tension_rho_age", 0)),
        strain_err=float(a.get("strain_err", 0.0)), dt_bending=float(a.get("dt_bending", 0.0)),
        bending_mode=xp.asarray(ds["bending_mode"].values) if "bending_mode" in ds else None,
        lipid_area=ds["lipid_area"].values.copy() if "lipid_area" in ds else None,
        **{k: ds[k].values.copy() for k in ("tension_secant", "tension_noise") if k in ds},
        limit_last=int(a.get("limit_last", -1)),
        limit_counts=[int(v) for v in np.atleast_1d(a["limit_counts"])] if "limit_counts" in a else None,
        limit_dt=[float(v) for v in np.atleast_1d(a["limit_dt"])] if "limit_dt" in a else None,
        dt_error=float(a.get("dt_error", 0.0)),
    )
    u_hat = ds["u_hat_re"].values + 1j * ds["u_hat_im"].values if "u_hat_re" in ds else None
    return st, u_hat


class TrajectoryWriter:
    """Appends frames to trajectory.partial.nc (unlimited time dimension); finalize() renames it."""

    LIMIT_VARS = frame_variables()  # which limit set the steps (step_limits): name -> (netCDF type, attributes)
    FRAME_VARS = ("t_tau", "tension", "area", "volume", "area_drift", "volume_drift", "bending_energy",
                  "tension_energy", "flow_sign", "dt_tau", "cg_iterations", "mesh_quality_min",
                  "mesh_quality_median", "triangle_strain_max", *LIMIT_VARS)

    VELOCITY_VARS = ("node_ux", "node_uy", "node_uz")

    def __init__(self, outdir: Path, faces, n_nodes: int, attrs: dict, resume_frames: int | None,
                 velocity: bool = False):
        self.path = outdir / PARTIAL
        self.faces = np.asarray(faces)
        self.n_nodes = int(n_nodes)
        self.attrs = attrs
        self.velocity = bool(velocity)
        self._pending, self._late_velocity, self._warned = [], None, False
        if resume_frames is None or not self.path.exists():
            self._create()
        else:
            self._truncate(resume_frames)

    def _create(self):
        import netCDF4

        tmp = self.path.with_suffix(".creating")
        with netCDF4.Dataset(tmp, "w") as nc:
            nc.createDimension("time", None)
            nc.createDimension("n_node", self.n_nodes)
            nc.createDimension("n_face", len(self.faces))
            nc.createDimension("n_vertex_per_face", 3)
            fv = nc.createVariable("face_node_connectivity", "i4", ("n_face", "n_vertex_per_face"))
            fv[:] = self.faces
            fv.setncatts(FACE_NODE_ATTRS)
            for name in ("node_x", "node_y", "node_z"):
                v = nc.createVariable(name, "f8", ("time", "n_node"), zlib=True, complevel=1)
                v.setncatts(cf_unit_attrs({"units": "R", **NODE_FIELD_ATTRS}))
            if self.velocity:
                for name in self.VELOCITY_VARS:
                    v = nc.createVariable(name, "f8", ("time", "n_node"), zlib=True, complevel=1)
                    v.setncatts(cf_unit_attrs({"units": "R/tau", **NODE_FIELD_ATTRS, "long_name": (
                        "membrane velocity dX/dt of the step taken from this frame (background flow included)")}))
            v = nc.createVariable("face_tension", "f4", ("time", "n_face"), zlib=True, complevel=1)
            v.setncatts(cf_unit_attrs({"units": "kappa/R^2", **FACE_FIELD_ATTRS, "long_name": (
                "local surface tension per triangle (penalty Lambda (A_l - A_l0)/A_l0, or the solved tension)")}))
            units = {"t_tau": "tau", "tension": "kappa/R^2", "area": "R^2", "volume": "R^3", "area_drift": "1",
                     "volume_drift": "1", "bending_energy": "kappa", "tension_energy": "kappa", "flow_sign": "1",
                     "dt_tau": "tau", "cg_iterations": "1", "mesh_quality_min": "1", "mesh_quality_median": "1",
                     "triangle_strain_max": "1"}
            for name in self.FRAME_VARS:
                kind, attrs = self.LIMIT_VARS.get(name, ("f8", {"units": units.get(name)}))
                v = nc.createVariable(name, kind, ("time",))
                v.setncatts(cf_unit_attrs(attrs))
            for k, val in {**self.attrs, **{k: v for k, v in SCALE_ATTRS.items() if k not in self.attrs}}.items():
                nc.setncattr(k, val)
            nc.setncattr("complete", 0)
        os.replace(tmp, self.path)

    def _truncate(self, n):
        """Drop frames written after the checkpoint we resume from (they will be recomputed identically)."""
        import xarray as xr

        with xr.open_dataset(self.path) as ds:
            if ds.sizes["time"] == n:
                return
            if ds.sizes["time"] < n:
                raise NumericalInstability(f"{self.path} holds fewer frames than its checkpoint; "
                                           "delete the run directory")
            kept = ds.isel(time=slice(0, n)).load()
        kept.encoding = {}
        atomic_to_netcdf(kept, self.path, unlimited_dims=["time"])

    def append(self, X, face_tension, scalars: dict):
        """Queue a frame and write every queued frame (see :meth:`flush`)."""
        self._pending.append({"X": np.array(X, dtype=float), "tension": np.array(face_tension),
                              "scalars": {k: float(scalars[k]) for k in self.FRAME_VARS}, "U": None})
        self.flush()

    def set_velocity(self, U):
        """The velocity of the last frame: the step from it is only known after the frame."""
        U = np.array(U, dtype=float)
        if self._pending:
            self._pending[-1]["U"] = U
        else:
            self._late_velocity = U
        self.flush()

    def flush(self, wait_s: float = 0.0) -> bool:
        """Write the frames still held in memory; True when none is left.

        Another program reading trajectory.partial.nc (an open xarray Dataset: HDF5 locks the file) makes the write
        fail. The run must not die of that, so the frames stay in memory and the next frame, checkpoint or the end
        tries again; ``wait_s``: keep trying that long (checkpoints and the end must not run ahead of the file)."""
        import sys
        import time

        deadline = time.monotonic() + float(wait_s)
        while True:
            try:
                self._write_pending()
                return True
            except OSError as exc:
                if not self._warned:
                    print(f"[vesicle run] warning: cannot write {self.path} ({exc}); is another program holding it "
                          "open? Frames are kept in memory and written once it is free (copy the file to read it "
                          "while a run goes)", file=sys.stderr, flush=True)
                    self._warned = True
                if time.monotonic() >= deadline:
                    return False
                time.sleep(0.5)

    def _write_pending(self):
        import netCDF4

        if not self._pending and self._late_velocity is None:
            return
        with netCDF4.Dataset(self.path, "a") as nc:
            if self._late_velocity is not None:
                i = nc.dimensions["time"].size - 1
                for c, name in enumerate(self.VELOCITY_VARS):
                    nc[name][i, :] = self._late_velocity[:, c]
                self._late_velocity = None
            while self._pending:
                f = self._pending[0]
                i = nc.dimensions["time"].size
                nc["node_x"][i, :] = f["X"][:, 0]
                nc["node_y"][i, :] = f["X"][:, 1]
                nc["node_z"][i, :] = f["X"][:, 2]
                nc["face_tension"][i, :] = f["tension"]
                for k in self.FRAME_VARS:
                    if k in nc.variables:  # a run resumed from a file of an older version lacks the newer ones
                        nc[k][i] = f["scalars"][k]
                if f["U"] is not None:
                    for c, name in enumerate(self.VELOCITY_VARS):
                        nc[name][i, :] = f["U"][:, c]
                self._pending.pop(0)

    def finalize(self, t_reverse_tau: float, chi: float, extra_attrs: dict) -> Path:
        """Add the time coordinate gamma_dot (t - t_reverse), mark complete, and move to trajectory.nc."""
        import xarray as xr

        if not self.flush(wait_s=FINAL_WAIT_S):
            raise OSError(f"{self.path} stayed locked for {FINAL_WAIT_S:g} s: close the program that holds it and "
                          "rerun (the run resumes from its checkpoint)")

        with xr.open_dataset(self.path) as ds:
            ds = ds.load()
        scale = chi if chi > 0 else 1.0
        ds = ds.assign_coords(time=("time", scale * (ds["t_tau"].values - t_reverse_tau)))
        ds["time"].attrs.update(units="1/gamma_dot" if chi > 0 else "tau",
                                long_name="time since the flow reversal, gamma_dot (t - t0)")
        ds = ds.set_coords("t_tau")
        ds = _as_ugrid(ds)
        ds.attrs.update(extra_attrs)
        ds.attrs["complete"] = 1
        enc = {k: {"zlib": True, "complevel": 1} for k in ("node_x", "node_y", "node_z", "face_tension")}
        final = self.path.with_name(TRAJECTORY)
        atomic_to_netcdf(ds, final, encoding=enc)
        self.path.unlink()
        return final


def _as_ugrid(ds):
    """The finished trajectory as a UGRID 1.0 mesh (mesh topology, node_lon/node_lat of the first frame, node and
    face fields tagged) with CF units; only attributes and these new variables change, no stored value."""
    X0 = np.stack([ds[f"node_{c}"].values[0] for c in "xyz"], axis=1)
    ds = ds.assign(ugrid_variables(X0))
    ds["face_node_connectivity"].attrs.update(FACE_NODE_ATTRS)
    for name, var in ds.variables.items():
        tags = NODE_FIELD_ATTRS if "n_node" in var.dims and name not in ("node_lon", "node_lat") else (
            FACE_FIELD_ATTRS if "n_face" in var.dims and name != "face_node_connectivity" else {})
        var.attrs = cf_unit_attrs({**var.attrs, **tags})
    ds["node_lon"].attrs["long_name"] += " in the first frame"
    ds["node_lat"].attrs["long_name"] += " in the first frame"
    ds.attrs = {**ds.attrs, **{k: v for k, v in SCALE_ATTRS.items() if k not in ds.attrs}}
    ds.attrs["Conventions"] = "CF-1.10 UGRID-1.0"
    return ds


def write_failure(path: Path, X, attrs: dict) -> None:
    """The diagnostic of a stopped run: vertex positions X (V, 3) at the failure, the message and where it
    happened in ``attrs`` (message, step, t_tau, dt, phase)."""
    import xarray as xr

    atomic_to_netcdf(xr.Dataset({"X": (("n_node", "xyz"), X)}, attrs=attrs), path)
