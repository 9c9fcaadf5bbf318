"""The IBM time loop (Sec. IV): stretch in the forward flow, reverse it, follow the wrinkling.

Per step (eq. 29, explicit in the membrane forces):
    F^n      = F_b(X^n) + F_sigma(X^n) (+ optional global penalties)         (A7)
    f^n      = S F^n           spreading with the 4-point delta                (28)
    Gamma^n  = int_{t_n}^{t_{n+1}} u_ind dt   periodic Stokes                  (23), (29)
    X^{n+1}  = X^n + J Gamma^n + u_inf(X^n) dt                                  (29)
In the steady-Stokes limit (Re -> 0, the default) Gamma^n = u_ind(f^n) dt.

Units: lengths in R, mu = kappa = 1, time in tau = mu R^3/kappa; the background rate is chi. All
durations in the run configuration are in gamma_dot t (= chi t/tau) when chi > 0.

Phases: from the initial ellipsoid a stretching phase in the forward flow u_inf = chi (x, -y, 0)
lasts ``stretch`` (gamma_dot t) or until the shape is stationary, then the flow reverses (Fig. 1)
and the run continues to ``t_end`` (gamma_dot t after the reversal).

Time step. Explicit stepping is limited by the stiffest membrane mode: the area penalty
(dt ~ 40 h / Lambda) or bending (dt ~ 13 h^3), both measured by power iteration. ``dt_rule="power"`` (default)
measures the largest eigenvalue |lam| of the linearised velocity operator dX/dt = M F(X) by power
iteration at the initial shape and takes dt = safety * 2 / |lam| (explicit Euler is stable for
|lam| dt < 2 on the real negative spectrum), capped by the formula estimate and by 0.01 / chi so the
flow is resolved; ``dt_rule="formula"`` uses the formula only; a number fixes dt (in tau).

Robustness. Output frames are appended to ``trajectory.partial.nc``; it becomes ``trajectory.nc``
only when the run is complete. ``checkpoint.nc`` is rewritten atomically every ``checkpoint_every``
steps; rerunning the same command resumes from it and ends bit-identical to an uninterrupted run.
NaN/Inf, a blow-up or an area/volume drift beyond ``max_drift`` stops the run with
NumericalInstability, a diagnostic file ``failure.nc`` and no complete-looking trajectory.
"""

from __future__ import annotations

import logging
import math
import os
import sys
import time as _time
from dataclasses import asdict, dataclass, field, fields, make_dataclass
from pathlib import Path

import numpy as np

from . import membrane as B
from .errors import ConfigError, NumericalInstability
from .io import atomic_to_netcdf

log = logging.getLogger("vesicle_core.simulate")

TRAJECTORY = "trajectory.nc"
PARTIAL = "trajectory.partial.nc"
CHECKPOINT = "checkpoint.nc"
FAILURE = "failure.nc"


# --------------------------------------------------------------------------- configuration
class _RunConfigRules:
    """Parameters of one IBM run, in solver units (see module docstring): the fields, defaults and ranges of
    :data:`vesicle_core.parameters.RUN_PARAMETERS`, checked on creation, plus the rules that tie them together."""

    def __post_init__(self):
        from .parameters import RUN_PARAMETERS

        for p in RUN_PARAMETERS:  # a frozen dataclass: store the normalised value (e.g. 128.0 -> 128)
            object.__setattr__(self, p.name, p.check(getattr(self, p.name)))
        if self.scheme == "inextensible" and self.Re > 0:
            raise ConfigError(f"scheme 'inextensible' solves steady Stokes (Re = 0); got Re = {self.Re:g}")
        if self.chi == 0 and self.stretch > 0:
            raise ConfigError("stretch must be 0 when chi = 0 (no flow to stretch in); t_end is then in tau")
        if self.seed_spectrum != "mesh" and self.stationary_tol > 0:
            raise ConfigError("seed_spectrum 'thermal' needs a fixed stretch (stationary_tol = 0): the seed goes on "
                              "the shape before the frame at the reversal")

    @property
    def h(self) -> float:
        return self.L / self.N

    @property
    def Lambda_eff(self) -> float:
        return default_lambda(self.chi, self.scheme) if self.Lambda is None else float(self.Lambda)

    @property
    def rho_bar(self) -> float:
        """Density in solver units: Re / chi (App. B with time in tau)."""
        return self.Re / self.chi if self.chi > 0 else 0.0

    def time_scale(self) -> float:
        """tau per unit of the configured durations: 1/chi, or 1 when chi = 0."""
        return 1.0 / self.chi if self.chi > 0 else 1.0

    @classmethod
    def from_dict(cls, d: dict) -> RunConfig:
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ConfigError(f"unknown run parameter(s) {unknown}; allowed: {sorted(names)}")
        return cls(**d)

    def as_attrs(self) -> dict:
        out = {}
        for k, v in asdict(self).items():
            out[k] = "default" if v is None else v
        out["Lambda_eff"] = self.Lambda_eff
        out["h"] = self.h
        return out


def _run_config_class():
    from .parameters import RUN_PARAMETERS

    types = {"float": float, "int": int, "str": str, "bool": bool}
    spec = [(p.name, types[p.kind] | None if p.nullable else types[p.kind], field(default=p.default))
            for p in RUN_PARAMETERS]
    cls = make_dataclass("RunConfig", spec, bases=(_RunConfigRules,), frozen=True)
    cls.__module__, cls.__doc__ = __name__, _RunConfigRules.__doc__  # so pickle and help() find it here
    return cls


RunConfig = _run_config_class()


SCHEMES = ("explicit", "projection", "inextensible")


def default_lambda(chi: float, scheme: str = "explicit") -> float:
    """Default tension modulus of (A5) [kappa/R^2].

    explicit:   the penalty alone holds the area, so the area strain sigma/Lambda must stay below ~0.2%.
                The stretched steady state has sigma ~ 26 chi kappa/R^2 (1770 measured at chi = 67), so
                Lambda = 1.5e4 chi with a floor of 1e5 (1e6 at chi = 67, 4e6 at chi = 268), strain ~0.18%.
    projection: a global multiplier carries the mean tension and holds the total area exactly; the local
                penalty only has to resist tension *differences* along the membrane, so it is 10x softer
                (1.5e3 chi, floor 1e4), which makes the explicit step limit 40 h/Lambda 10x larger.
    inextensible: Lambda is the area-stretch modulus of the constraint (strain sigma/Lambda), treated
                implicitly, so it costs no time step: 5e4 chi (floor 1e6) keeps the strain near 5e-4.
    """
    if scheme == "inextensible":
        return max(1.0e6, 5.0e4 * chi)
    if scheme == "projection":
        return max(1.0e4, 1.5e3 * chi)
    return max(1.0e5, 1.5e4 * chi)


def load_config(path) -> RunConfig:
    import yaml

    try:
        with open(path) as fh:
            d = yaml.safe_load(fh) or {}
    except FileNotFoundError:
        raise ConfigError(f"parameter file {path} does not exist") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"parameter file {path} is not valid YAML: {exc}") from None
    if not isinstance(d, dict):
        raise ConfigError(f"parameter file {path} must hold a mapping of run parameters")
    try:
        return RunConfig.from_dict(d)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


# --------------------------------------------------------------------------- the coupled operator
class IBMSolver:
    """Membrane forces + spreading + periodic Stokes + interpolation on one array module."""

    def __init__(self, faces, X0, cfg: RunConfig):
        from .backend import get_backend
        from .ibm import Coupler, Grid
        from .stokes import StokesSolver

        self.cfg = cfg
        self.be = get_backend(cfg.backend, cfg.dtype, fft_workers=cfg.fft_workers)
        xp = self.be.xp
        self.xp = xp
        self.grid = Grid(cfg.N, cfg.L)
        self.stokes = StokesSolver(self.grid, self.be, rho_bar=cfg.rho_bar)
        # reused stencil and grid buffers (no page faults per step)
        self.coupler = Coupler(self.grid, self.be, kernel=cfg.kernel)
        self._grid_buf = self.be.empty(self.grid.field_shape)
        # the inextensible scheme carries the tension as an unknown: no penalty (A5) in the force
        penalty = 0.0 if cfg.scheme == "inextensible" else cfg.Lambda_eff
        self.membrane = B.Membrane.from_mesh(
            xp.asarray(X0, dtype=xp.float64), faces, xp=xp, Lambda=penalty, K_volume=cfg.K_volume,
            K_area=cfg.K_area, area_model=cfg.area_model,
        )

    def forces(self, X):
        return self.membrane.forces(X)

    def induced_displacement(self, X, F, dt, advance=True, same_points=False):
        """J Gamma: the induced displacement of the vertices over dt (steady Stokes: J u_ind dt).

        ``advance``: at finite Re, step the stored fluid state (False: steady response, state untouched).
        ``same_points``: X is the same as in the previous call, so its stencil is reused.
        """
        if not same_points:
            self.coupler.prepare(X)
        f = self.coupler.spread(F)
        if self.cfg.rho_bar > 0 and not advance:
            G = self.stokes.velocity(f, out=self._grid_buf)
            G *= dt
        else:
            G = self.stokes.step(f, dt, out=self._grid_buf)
        return self.coupler.interpolate(G)

    def membrane_velocity(self, X):
        """Induced velocity of the membrane, steady Stokes, no background flow (for dt estimates)."""
        F, _ = self.forces(X)
        return self.induced_displacement(X, F, 1.0, advance=False)


def background_velocity(X, rate):
    from .flow import background_velocity as bv

    return bv(X, rate)


def formula_dt(cfg: RunConfig, edge_mean: float, flow: bool = True) -> float:
    """Stable-step estimate (tau) measured by power iteration on the linearised operator: area penalty
    40 h/Lambda, bending 13 h^3 (edge ~ h) to 20 h^3 (edge ~ 2h), and 0.01/chi so the background flow moves a
    vertex by < 1% of R per step."""
    h = cfg.h
    lam = (0.0 if cfg.scheme == "inextensible" else cfg.Lambda_eff) + cfg.K_area
    c_b = 13.0 + 7.0 * min(max(edge_mean / h - 1.0, 0.0), 1.0)
    limits = [c_b * h**3]
    if lam > 0:
        limits.append(40.0 * h / lam)
    if cfg.chi > 0 and flow:
        limits.append(0.01 / cfg.chi)
    return min(limits)


def power_dt(solver: IBMSolver, X, iters=30, seed=0) -> tuple[float, float]:
    """Largest |eigenvalue| of the linearised membrane velocity at X by power iteration -> (2/|lam|, |lam|).

    The Jacobian-vector product is a centred finite difference of the velocity (two solves).
    """
    xp = solver.xp
    rng = np.random.default_rng(seed)
    v = xp.asarray(rng.standard_normal(X.shape))
    v /= float(xp.linalg.norm(v))
    scale = 1e-7 * float(xp.abs(X).max())
    lam = 0.0
    for _ in range(iters):
        Jv = (solver.membrane_velocity(X + scale * v) - solver.membrane_velocity(X - scale * v)) / (2 * scale)
        new = float(xp.linalg.norm(Jv))
        if new == 0 or not math.isfinite(new):
            break
        v = Jv / new
        if abs(new - lam) < 1e-3 * new:
            lam = new
            break
        lam = new
    return (2.0 / lam if lam > 0 else math.inf), lam


# --------------------------------------------------------------------------- state, checkpoint, trajectory
@dataclass
class State:
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


def _save_checkpoint(path: Path, state: State, be, u_hat):
    import xarray as xr

    data = {"X": (("n_node", "xyz"), be.asnumpy(state.X))}
    if state.w is not None:
        data["w"] = (("n_node", "xyz"), be.asnumpy(state.w))
    for name in ("sigma", "sigma_prev"):
        if getattr(state, name) is not None:
            data[name] = (("n_face",), be.asnumpy(getattr(state, name)))
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
        "next_output_t": state.next_output_t,
    }
    if state.dt_steps:  # netCDF attributes cannot be empty
        attrs["dt_steps"] = np.asarray(state.dt_steps, dtype=float)
    atomic_to_netcdf(xr.Dataset(data, attrs=attrs), path)


def _load_checkpoint(path: Path, xp):
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
        next_output_t=float(a.get("next_output_t", 0.0)),
        dt_steps=tuple(np.atleast_1d(a.get("dt_steps", np.zeros(0))).tolist()),
        cg_iterations=[int(v) for v in ds["cg_iterations"].values] if "cg_iterations" in ds else [],
    )
    u_hat = ds["u_hat_re"].values + 1j * ds["u_hat_im"].values if "u_hat_re" in ds else None
    return st, u_hat


class TrajectoryWriter:
    """Appends frames to trajectory.partial.nc (unlimited time dimension); finalize() renames it."""

    FRAME_VARS = ("t_tau", "tension", "area", "volume", "area_drift", "volume_drift", "bending_energy",
                  "tension_energy", "flow_sign", "dt_tau", "cg_iterations")

    VELOCITY_VARS = ("node_ux", "node_uy", "node_uz")

    def __init__(self, outdir: Path, faces, n_nodes: int, attrs: dict, resume_frames: int | None,
                 velocity: bool = False):
        self.path = outdir / PARTIAL
        self.faces = np.asarray(faces)
        self.n_nodes = int(n_nodes)
        self.attrs = attrs
        self.velocity = bool(velocity)
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
            fv.cf_role = "face_node_connectivity"
            fv.start_index = 0
            for name in ("node_x", "node_y", "node_z"):
                v = nc.createVariable(name, "f8", ("time", "n_node"), zlib=True, complevel=1)
                v.units = "R"
            if self.velocity:
                for name in self.VELOCITY_VARS:
                    v = nc.createVariable(name, "f8", ("time", "n_node"), zlib=True, complevel=1)
                    v.units = "R/tau"
                    v.long_name = "membrane velocity dX/dt of the step taken from this frame (background flow included)"
            v = nc.createVariable("face_tension", "f4", ("time", "n_face"), zlib=True, complevel=1)
            v.units = "kappa/R^2"
            v.long_name = "local surface tension per triangle (penalty Lambda (A_l - A_l0)/A_l0, or the solved tension)"
            units = {"t_tau": "tau", "tension": "kappa/R^2", "area": "R^2", "volume": "R^3", "area_drift": "1",
                     "volume_drift": "1", "bending_energy": "kappa", "tension_energy": "kappa", "flow_sign": "1",
                     "dt_tau": "tau", "cg_iterations": "1"}
            for name in self.FRAME_VARS:
                v = nc.createVariable(name, "f8", ("time",))
                v.units = units[name]
            for k, val in self.attrs.items():
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
        import netCDF4

        with netCDF4.Dataset(self.path, "a") as nc:
            i = nc.dimensions["time"].size
            nc["node_x"][i, :] = X[:, 0]
            nc["node_y"][i, :] = X[:, 1]
            nc["node_z"][i, :] = X[:, 2]
            nc["face_tension"][i, :] = face_tension
            for k in self.FRAME_VARS:
                nc[k][i] = scalars[k]

    def set_velocity(self, U):
        """The velocity of the last frame written: the step from it is only known after the frame."""
        import netCDF4

        with netCDF4.Dataset(self.path, "a") as nc:
            i = nc.dimensions["time"].size - 1
            for c, name in enumerate(self.VELOCITY_VARS):
                nc[name][i, :] = U[:, c]

    def finalize(self, t_reverse_tau: float, chi: float, extra_attrs: dict) -> Path:
        """Add the time coordinate gamma_dot (t - t_reverse), mark complete, and move to trajectory.nc."""
        import xarray as xr

        with xr.open_dataset(self.path) as ds:
            ds = ds.load()
        scale = chi if chi > 0 else 1.0
        ds = ds.assign_coords(time=("time", scale * (ds["t_tau"].values - t_reverse_tau)))
        ds["time"].attrs.update(units="1/gamma_dot" if chi > 0 else "tau",
                                long_name="time since the flow reversal, gamma_dot (t - t0)")
        ds = ds.set_coords("t_tau")
        ds.attrs.update(extra_attrs)
        ds.attrs["complete"] = 1
        enc = {k: {"zlib": True, "complevel": 1} for k in ("node_x", "node_y", "node_z", "face_tension")}
        final = self.path.with_name(TRAJECTORY)
        atomic_to_netcdf(ds, final, encoding=enc)
        self.path.unlink()
        return final


# --------------------------------------------------------------------------- the run
def _shape_moments(X, xp):
    c = X - X.mean(axis=0)
    return tuple(float(v) for v in (c * c).mean(axis=0))


class _Progress:
    """tqdm bar on a terminal, plain log lines (every 5%) otherwise.

    ``unit``: what n counts, "step" (fixed steps) or "permille" (adaptive steps: per mille of the simulated time,
    the step count then goes in the postfix).
    """

    def __init__(self, total, initial, enabled, unit="step"):
        self.total, self.n = total, initial
        self.unit = unit
        self.bar = None
        self.t0 = _time.perf_counter()
        self.n0 = initial
        self.last_pct = -1
        self.enabled = enabled
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=initial, unit="step" if unit == "step" else "\u2030",
                            dynamic_ncols=True, smoothing=0.05)

    def update(self, n, postfix=None):
        if self.bar is not None:
            self.bar.update(n - self.n)
            if postfix:
                self.bar.set_postfix_str(postfix, refresh=False)
        elif self.enabled:
            pct = int(100 * n / max(self.total, 1)) // 5 * 5
            if pct != self.last_pct:
                self.last_pct = pct
                el = _time.perf_counter() - self.t0
                rate = (n - self.n0) / el if el > 0 else 0.0
                eta = (self.total - n) / rate if rate > 0 else float("nan")
                count = f"step {n}/{self.total}  {rate:.1f} steps/s" if self.unit == "step" else ""
                print(f"[vesicle run] {pct:3d}%  {count}  ETA {eta:.0f} s" + (f"  {postfix}" if postfix else ""),
                      file=sys.stderr, flush=True)
        self.n = n

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _reverse(state: State, bar, relax_steps, cfg: RunConfig, stationary: bool, on_reverse=None):
    """Flip the background flow (Fig. 1): the reversal time t0 is the current time. ``on_reverse(state)`` runs
    first (the wrinkle seed)."""
    if on_reverse is not None:
        on_reverse(state)
    state.phase, state.t_reverse = "relax", state.t
    if relax_steps is not None:  # step-count progress; adaptive runs count simulated time instead
        bar.total = state.step + relax_steps
        if bar.bar is not None:
            bar.bar.total = bar.total
    log.info("flow reversed at gamma_dot t = %.4f (%s)", state.t * cfg.chi,
             "shape stationary" if stationary else "end of the stretching phase")


def run(mesh, cfg: RunConfig, outdir, progress: bool = True, stop_after_steps: int | None = None) -> Path:
    """Run (or resume) one case; returns the path of the complete trajectory.

    ``stop_after_steps`` ends the process early as if interrupted (used by the resume test).
    """
    from . import __version__

    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    ckpt = outdir / CHECKPOINT
    (outdir / FAILURE).unlink(missing_ok=True)

    mesh.check()
    solver = IBMSolver(mesh.faces, mesh.vertices, cfg)
    xp, be = solver.xp, solver.be
    mem = solver.membrane
    A0, V0 = mem.ref.area, mem.ref.volume
    T = cfg.time_scale()

    seed_info = {}

    def seed_shape(state):
        """The thermal wrinkle seed at the reversal (seeding.py); mesh noise only by default."""
        if cfg.seed_spectrum != "thermal":
            return
        from .seeding import thermal_seed
        from .units import S_from_chi

        S = S_from_chi(cfg.chi, float(mesh.excess_area())) if cfg.chi > 0 else 0.0
        X_new, l_seed = thermal_seed(be.asnumpy(state.X), mesh.faces, delta=float(mesh.excess_area()), S=S,
                                     seed=cfg.seed, scale=cfg.seed_scale)
        state.X = xp.asarray(X_new, dtype=xp.float64)
        seed_info["seed_l_max"] = l_seed
        log.info("thermal wrinkle seed (x%g k_B T, seed %d) on 3 <= l <= %d at the reversal", cfg.seed_scale, cfg.seed,
                 l_seed)

    resumed = ckpt.exists()
    if resumed:
        state, u_hat = _load_checkpoint(ckpt, xp)
        if u_hat is not None:
            solver.stokes.state = {"rho_bar": cfg.rho_bar, "u_hat": u_hat}
        dt = state.dt
        log.info("resuming %s from step %d (t = %.6g tau)", outdir, state.step, state.t)
    else:
        state = State(X=xp.asarray(mesh.vertices, dtype=xp.float64))
        edge = mesh.quality()["edge_mean"]
        dt_f = formula_dt(cfg, edge)
        if isinstance(cfg.dt, str) and cfg.scheme == "inextensible":
            # the stability limit of the bending force; the integrator adds tension, growth and flow limits
            dt = 2.0 * formula_dt(cfg, edge, flow=False)
            if cfg.dt == "power":
                dt_p, lam = power_dt(solver, state.X)
                log.info("power iteration (bending): |lam|max = %.4g /tau -> dt_crit = %.4g tau", lam, dt_p)
                dt = min(dt_p, dt)
        elif isinstance(cfg.dt, str):
            if cfg.dt == "power":
                dt_p, lam = power_dt(solver, state.X)
                dt = cfg.dt_safety * min(dt_p, 2.0 * dt_f)
                log.info("power iteration: |lam|max = %.4g /tau -> dt_crit = %.4g tau (formula %.4g)", lam, dt_p, dt_f)
            else:
                dt = cfg.dt_safety * dt_f
            if cfg.chi > 0:
                dt = min(dt, 0.01 / cfg.chi)
        else:
            dt = float(cfg.dt)
        state.dt = dt
        state.shape_prev = _shape_moments(state.X, xp)
        if cfg.stretch == 0:
            seed_shape(state)
            state.phase, state.t_reverse = "relax", 0.0

    from .integrators import SCHEMES as INTEGRATORS

    integ = INTEGRATORS[cfg.scheme](solver, dt)
    adaptive = integ.adaptive and isinstance(cfg.dt, str)
    integ.adaptive = adaptive
    if state.cg_iterations is None:
        state.cg_iterations = []
    if hasattr(integ, "iterations"):
        integ.iterations = state.cg_iterations
    out_steps = max(1, int(round(cfg.output_every * T / dt)))
    stretch_steps = int(math.ceil(cfg.stretch * T / dt))
    relax_steps = int(math.ceil(cfg.t_end * T / dt))

    attrs = {
        **{f"mesh_{k}": v for k, v in mesh.attrs.items() if isinstance(v, (int, float, str, np.number))},
        **{k: v for k, v in cfg.as_attrs().items()},
        "delta": float(mesh.excess_area()), "dt_tau": dt, "dt_gamma": dt * cfg.chi, "A0": A0, "V0": V0,
        "dt_rule": "adaptive (bending, tension, PA growth, flow)" if adaptive else "fixed",
        "backend": be.name, "source": f"vesicle_core {__version__}", "Conventions": "CF-1.10",
        "title": "IBM trajectory of a vesicle in a reversed elongational flow",
        "rho_bar": cfg.rho_bar,
    }
    if cfg.chi > 0:
        from .units import S_from_chi

        attrs["S"] = S_from_chi(cfg.chi, attrs["delta"])
    attrs = {k: (str(v) if isinstance(v, bool) else v) for k, v in attrs.items()}

    writer = TrajectoryWriter(outdir, mesh.faces, mesh.n_vertices, attrs, state.n_frames if resumed else None,
                              velocity=cfg.store_velocity)

    if adaptive:  # progress in per mille of the simulated time
        total_est = 1000
        done_frac = 0 if state.phase == "stretch" else int(1000 * cfg.stretch / max(cfg.stretch + cfg.t_end, 1e-300))
        bar = _Progress(total_est, done_frac, progress, unit="permille")
    else:
        if state.phase == "relax":
            total_est = int(round(state.t_reverse / dt)) + relax_steps
        else:
            total_est = stretch_steps + relax_steps
        bar = _Progress(total_est, state.step, progress)
    wall0 = _time.perf_counter()
    steps_this_call = 0
    eps_t = 1e-9 * T
    t_stretch_end = cfg.stretch * T
    t_out = cfg.output_every * T

    def frame(X, F, geo, dt_step):
        sig_l = integ.face_tension(state, geo)
        A = float(geo.area.sum())
        V = B.enclosed_volume(X, mem.topo, geo)
        sig = B.global_tension(geo, sig_l) + (cfg.K_area * (A - A0) / A0 if cfg.K_area else 0.0)
        flow_sign = 1.0 if state.phase == "stretch" else -1.0
        sc = {"t_tau": state.t, "tension": sig, "area": A, "volume": V, "area_drift": A / A0 - 1,
              "volume_drift": V / V0 - 1,
              "bending_energy": B.bending_energy(X, mem.topo, mem.kappa, geo, mem.area_model),
              "tension_energy": B.tension_energy(geo, mem.ref, mem.Lambda), "flow_sign": flow_sign}
        if not all(math.isfinite(v) for v in sc.values()):
            fail("non-finite energy or tension", X)
        if abs(sc["area_drift"]) > cfg.max_drift or abs(sc["volume_drift"]) > cfg.max_drift:
            fail(f"area drift {sc['area_drift']:.3%} or volume drift {sc['volume_drift']:.3%} exceeds "
                 f"max_drift = {cfg.max_drift:g}; lower dt or raise Lambda", X)
        sc["dt_tau"] = dt_step
        sc["cg_iterations"] = float(state.cg_iterations[-1]) if state.cg_iterations else 0.0
        writer.append(be.asnumpy(X), be.asnumpy(sig_l).astype(np.float32), sc)
        state.n_frames += 1
        return sc

    def fail(msg, X):
        import xarray as xr

        diag = xr.Dataset({"X": (("n_node", "xyz"), be.asnumpy(X))},
                          attrs={"message": msg, "step": state.step, "t_tau": state.t, "dt": dt, "phase": state.phase})
        atomic_to_netcdf(diag, outdir / FAILURE)
        bar.close()
        raise NumericalInstability(f"{msg} (step {state.step}, t = {state.t:.6g} tau); "
                                   f"state written to {outdir / FAILURE}")

    def next_frame_time():
        base = state.t_reverse if state.phase == "relax" else 0.0
        k = math.floor((state.t - base) / t_out + 0.5)
        return base + (k + 1) * t_out

    dt_step = 0.0 if adaptive else dt  # the step that led to the frame (none before the first)
    try:
        while True:
            if adaptive:
                if state.phase == "stretch" and state.t >= t_stretch_end - eps_t:
                    _reverse(state, bar, None, cfg, stationary=False, on_reverse=seed_shape)
                    state.next_output_t = state.t
                done = state.phase == "relax" and state.t >= state.t_reverse + cfg.t_end * T - eps_t
                if done:
                    state.next_output_t = state.t
                output_due = state.t >= state.next_output_t - eps_t
            else:
                # phase changes depend on the step count only, so a resumed run takes them at the same steps
                if state.phase == "stretch" and state.step >= stretch_steps:
                    _reverse(state, bar, relax_steps, cfg, stationary=False, on_reverse=seed_shape)
                    state.next_output = state.step  # a frame at t0 exactly; later frames every output_every
                done = state.phase == "relax" and state.t - state.t_reverse >= cfg.t_end * T - 0.5 * dt
                if done:
                    state.next_output = state.step  # the last frame is always written
                output_due = state.step == state.next_output
            X = state.X  # the reversal may have seeded the shape
            F, geo = solver.forces(X)
            if output_due:
                sc = frame(X, F, geo, dt_step)
                state.next_output = state.step + out_steps
                state.next_output_t = next_frame_time()
                t_show = cfg.chi * (state.t - state.t_reverse) if state.phase == "relax" else cfg.chi * state.t
                info = f"{state.phase} gt={t_show:.3f} sigma={sc['tension']:.4g} dA={sc['area_drift']:.1e}"
                if adaptive:
                    info = f"step {state.step} {info} dt={dt_step:.2e} cg={sc['cg_iterations']:.0f}"
                    T_all = (cfg.stretch + cfg.t_end) * T
                    t_done = state.t if state.phase == "stretch" else t_stretch_end + state.t - state.t_reverse
                    bar.update(min(1000, int(1000 * t_done / max(T_all, 1e-300))), info)
                else:
                    bar.update(state.step, info)
                if state.phase == "stretch" and cfg.stationary_tol > 0 and state.step > 0:
                    mom = _shape_moments(X, xp)
                    rate = max(abs(a - b) / b for a, b in zip(mom, state.shape_prev, strict=True)) / cfg.output_every
                    state.shape_prev = mom
                    if rate < cfg.stationary_tol:
                        _reverse(state, bar, None if adaptive else relax_steps, cfg, stationary=True)  # frame at t0
                        state.next_output_t = next_frame_time()
            rate = cfg.chi * (1.0 if state.phase == "stretch" else -1.0)
            if done:
                if cfg.store_velocity:  # the velocity at the last frame: one step computed, not taken
                    dt_last = dt_step if dt_step > 0 else dt
                    writer.set_velocity(be.asnumpy(integ.step(state, X, F, geo, dt_last, rate)) / dt_last)
                break
            if adaptive:
                # land exactly on the next frame, the reversal or the end, in equal steps
                t_event = state.next_output_t
                t_event = min(t_event, t_stretch_end if state.phase == "stretch"
                              else state.t_reverse + cfg.t_end * T)
                dt_want = integ.next_dt(state, geo)
                if not dt_want > 1e-14 * T:
                    fail(f"time step collapsed to {dt_want:.3g} tau", X)
                remaining = t_event - state.t
                dt_step = remaining / max(1, math.ceil(remaining / dt_want - 1e-6))
            else:
                dt_step = dt
            dX = integ.step(state, X, F, geo, dt_step, rate)
            if output_due and cfg.store_velocity:
                writer.set_velocity(be.asnumpy(dX) / dt_step)
            state.X = X + dX
            state.step += 1
            state.t = state.t + dt_step
            if adaptive and abs(state.t - t_event) < eps_t:
                state.t = t_event
            steps_this_call += 1
            if state.step % 16 == 0 and not bool(xp.isfinite(state.X).all()):
                fail("NaN or Inf in vertex positions (time step too large?)", X)
            if state.step % cfg.checkpoint_every == 0:
                _save_checkpoint(ckpt, state, be, solver.stokes.state["u_hat"] if cfg.rho_bar > 0 else None)
            if stop_after_steps is not None and steps_this_call >= stop_after_steps:
                bar.close()
                return None
    except NumericalInstability as exc:
        if not (outdir / FAILURE).exists():  # raised inside a solve (e.g. CG did not converge)
            fail(str(exc), state.X)
        raise
    except KeyboardInterrupt:
        bar.close()
        log.warning("interrupted at step %d; rerun the same command to resume from the last checkpoint", state.step)
        raise
    bar.close()
    wall = _time.perf_counter() - wall0
    extra = {**integ.stats(), **seed_info, "steps": state.step, "wall_time_s_last_call": wall,
             "t_reverse_tau": state.t_reverse, "t_reverse_gamma": state.t_reverse * cfg.chi, "resumed": int(resumed)}
    if adaptive and state.step > 0:  # the mean step (each frame stores its own in dt_tau)
        extra.update(dt_tau=state.t / state.step, dt_gamma=cfg.chi * state.t / state.step, dt_bending_tau=dt)
    path = writer.finalize(state.t_reverse, cfg.chi, extra)
    ckpt.unlink(missing_ok=True)
    return path
