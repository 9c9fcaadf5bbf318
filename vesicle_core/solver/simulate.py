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

Time step: :mod:`vesicle_core.solver.step_size`.

Robustness. Output frames are appended to ``trajectory.partial.nc``; it becomes ``trajectory.nc``
only when the run is complete. ``checkpoint.nc`` is rewritten atomically every ``checkpoint_every``
steps, after every ``parameters.CHECKPOINT_WALL_S`` of wall time and on SIGINT/SIGTERM; rerunning the same
command resumes from it and ends bit-identical to an uninterrupted run. NaN/Inf, a blow-up or an area/volume drift
beyond ``max_drift`` stops the run with NumericalInstability, a diagnostic file ``failure.nc`` and no complete-looking
trajectory. A second run into a directory another one is writing is refused (``run.lock``, io.hold_run_lock).

Layout: configuration in model.run_config; in this package the coupled operator (IBMSolver) in mobility, the run
directory's files in trajectory, the schemes in integrators, the steps in step_size; here the driver :func:`run`.
"""

from __future__ import annotations

import logging
import math
import signal
import sys
import time as _time
from pathlib import Path

import numpy as np

from ..errors import NumericalInstability
from ..geometry.mesh import vertices_for_edge
from ..io import hold_run_lock
from ..model.parameters import CHECKPOINT_WALL_S
from ..model.run_config import RunConfig
from ..xp import to_float, to_numpy
from . import membrane as B
from . import step_limits
from .fluctuations import noise_mesh_warning
from .mobility import IBMSolver
from .step_size import initial_dt
from .trajectory import CHECKPOINT, FAILURE, State, TrajectoryWriter, load_checkpoint, save_checkpoint, write_failure

__all__ = ["run"]

log = logging.getLogger("vesicle_core.solver.simulate")


def _shape_moments(X, xp):
    c = X - X.mean(axis=0)
    return tuple(float(v) for v in to_numpy((c * c).mean(axis=0)))


class _Progress:
    """tqdm bar on a terminal, plain log lines (every 5%) otherwise.

    ``unit``: what n counts, "step" (fixed steps) or "permille" (adaptive steps: per mille of the simulated time,
    the step count then goes in the postfix).
    """

    def __init__(self, total, initial, enabled, unit="step"):
        self.total, self.n, self.unit, self.bar = total, initial, unit, None
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


def _thermal_seed(state: State, mesh, cfg: RunConfig, solver: IBMSolver, seed_info: dict) -> None:
    """The thermal wrinkle seed at the reversal (seeding.py); mesh noise only by default."""
    if cfg.seed_spectrum != "thermal":
        return
    from ..model.units import S_from_chi
    from .seeding import thermal_seed

    S = S_from_chi(cfg.chi, float(mesh.excess_area())) if cfg.chi > 0 else 0.0
    X_new, l_seed = thermal_seed(solver.be.asnumpy(state.X), mesh.faces, delta=float(mesh.excess_area()), S=S,
                                 seed=cfg.seed, scale=cfg.seed_scale)
    state.X = solver.xp.asarray(X_new, dtype=solver.xp.float64)
    state.seed_l_max = seed_info["seed_l_max"] = int(l_seed)  # the state keeps it across a resume
    log.info("thermal wrinkle seed (x%g k_B T, seed %d) on 3 <= l <= %d at the reversal", cfg.seed_scale, cfg.seed,
             l_seed)


def _start(mesh, cfg: RunConfig, solver: IBMSolver, outdir: Path, seed) -> tuple[State, bool]:
    """The state to start from: the checkpoint in ``outdir`` if there is one (-> resumed = True), else the mesh
    with its base step; a run without stretching phase is seeded (``seed(state)``) and reversed at t = 0."""
    ckpt = outdir / CHECKPOINT
    if ckpt.exists():
        state, u_hat = load_checkpoint(ckpt, solver.xp)
        if u_hat is not None:
            solver.stokes.state = {"rho_bar": cfg.rho_bar, "u_hat": u_hat}
        log.info("resuming %s from step %d (t = %.6g tau)", outdir, state.step, state.t)
        return state, True
    xp = solver.xp
    state = State(X=xp.asarray(mesh.vertices, dtype=xp.float64))
    state.dt = initial_dt(cfg, solver, state.X, mesh.quality()["edge_mean"])
    state.shape_prev = _shape_moments(state.X, xp)
    if cfg.stretch == 0:
        seed(state)
        state.phase, state.t_reverse = "relax", 0.0
    return state, False


def _trajectory_attrs(mesh, cfg: RunConfig, solver: IBMSolver, dt: float, adaptive: bool) -> dict:
    """Global attributes of the trajectory: mesh and run parameters, the step rule and the derived groups."""
    from .. import __version__

    ref = solver.membrane.ref
    attrs = {
        **{f"mesh_{k}": v for k, v in mesh.attrs.items() if isinstance(v, (int, float, str, np.number))},
        **{k: v for k, v in cfg.as_attrs().items()},
        "delta": float(mesh.excess_area()), "dt_tau": dt, "dt_gamma": dt * cfg.chi, "A0": ref.area, "V0": ref.volume,
        "dt_rule": "adaptive (bending, tension, PA growth, flow)" if adaptive else "fixed",
        "backend": solver.be.name, "source": f"vesicle_core {__version__}", "Conventions": "CF-1.10",
        "title": "IBM trajectory of a vesicle in a reversed elongational flow",
        "rho_bar": cfg.rho_bar,
    }
    if cfg.chi > 0:
        from ..model.units import S_from_chi

        attrs["S"] = S_from_chi(cfg.chi, attrs["delta"])
    return {k: (str(v) if isinstance(v, bool) else v) for k, v in attrs.items()}


# The sharp coupling resolves what the markers resolve: with a mesh edge of 2h its l_res at N = 128 is 16 against 25
# with edge h, and l = 2 is off by up to 5.6% at N = 64 (docs/explanation/resolution.md, "Sharpened coupling")
SHARP_EDGE_MAX = 1.5
#: an adaptive step shorter than this fraction of the bending limit stops the run (exit 3): a collapsed step
DT_COLLAPSE = 1e-6


def _check_mesh_spacing(mesh, cfg: RunConfig) -> None:
    """Warn when the sharp coupling runs on markers much coarser than the grid (edge > SHARP_EDGE_MAX h), or with a
    kernel whose Fourier transform does not vanish at the grid's Nyquist wave number (the 3-point kernel: its resolved
    rates come out 2-6% fast with edge h, up to 41% with edge 2h; docs/explanation/resolution.md), or noise on
    markers much finer than the grid (fluctuations.noise_mesh_warning)."""
    edge = float(mesh.quality()["edge_mean"]) / cfg.h
    if cfg.kT > 0 and (message := noise_mesh_warning(edge)):
        log.warning(message)
    if cfg.coupling != "sharp":
        return
    if cfg.kernel == "roma3":
        log.warning("coupling 'sharp' with kernel 'roma3' overestimates the resolved modes' rates (by up to 6%% with a "
                    "mesh edge of h); use peskin4 or bao6")
    if edge > SHARP_EDGE_MAX:
        log.warning("coupling 'sharp' with a mean mesh edge of %.2f h (> %.1f h): it resolves little more than the "
                    "kernel coupling there; use a mesh of ~%d vertices (edge ~h) at N = %d", edge,
                    SHARP_EDGE_MAX, vertices_for_edge(cfg.h), cfg.N)


class _Run:
    """One call of :func:`run`: the case's solver, integrator, writer and progress, and the steps of its time loop.

    Time bookkeeping (tau): ``dt`` is the base step (the fixed step, or the bending-limited estimate of adaptive
    runs); fixed-step runs take the reversal, the end and the frames at step counts (``stretch_steps``,
    ``relax_steps``, ``out_steps``), adaptive runs at times (``t_stretch_end``, t_end, ``t_out``), landing on them
    within ``eps_t``.
    """

    def __init__(self, mesh, cfg: RunConfig, outdir: Path, progress: bool):
        from .schemes import integrator_class

        self.mesh, self.cfg, self.outdir = mesh, cfg, outdir
        _check_mesh_spacing(mesh, cfg)
        self.solver = solver = IBMSolver(mesh.faces, mesh.vertices, cfg)
        self.xp, self.be, self.mem = solver.xp, solver.be, solver.membrane
        self.A0, self.V0 = self.mem.ref.area, self.mem.ref.volume
        self.T = T = cfg.time_scale()
        self.seed_info = {}
        self.stop_signal = 0  # set by a SIGINT/SIGTERM handler (run()): stop after the current step
        self.state, self.resumed = _start(mesh, cfg, solver, outdir, self.seed_shape)
        state = self.state
        self.dt = dt = state.dt
        self.integ = integ = integrator_class(cfg)(solver, dt, X0=mesh.vertices)
        self.adaptive = integ.adaptive and isinstance(cfg.dt, str)  # a fixed dt overrides an adaptive scheme
        integ.adaptive = self.adaptive
        if state.cg_iterations is None:
            state.cg_iterations = []
        if hasattr(integ, "iterations"):
            integ.iterations = state.cg_iterations
        self.out_steps = max(1, int(round(cfg.output_every * T / dt)))
        self.stretch_steps = int(math.ceil(cfg.stretch * T / dt))
        self.relax_steps = int(math.ceil(cfg.t_end * T / dt))
        self.writer = TrajectoryWriter(outdir, mesh.faces, mesh.n_vertices,
                                       _trajectory_attrs(mesh, cfg, solver, dt, self.adaptive),
                                       state.n_frames if self.resumed else None, velocity=cfg.store_velocity)
        self.bar = self._progress_bar(progress)
        self.wall0 = self.last_checkpoint = _time.perf_counter()
        self.steps_this_call = 0
        self.eps_t = 1e-9 * T
        self.t_stretch_end = cfg.stretch * T
        self.t_out = cfg.output_every * T
        self.dt_step = 0.0 if self.adaptive else dt  # the step that led to the frame (none before the first)
        if state.seed_l_max >= 0:
            self.seed_info["seed_l_max"] = state.seed_l_max

    def _progress_bar(self, enabled: bool) -> _Progress:
        cfg, state = self.cfg, self.state
        if self.adaptive:  # progress in per mille of the simulated time
            span = max(cfg.stretch + cfg.t_end, 1e-300)
            done_frac = 0 if state.phase == "stretch" else int(1000 * cfg.stretch / span)
            return _Progress(1000, done_frac, enabled, unit="permille")
        if state.phase == "relax":
            total_est = int(round(state.t_reverse / self.dt)) + self.relax_steps
        else:
            total_est = self.stretch_steps + self.relax_steps
        return _Progress(total_est, state.step, enabled)

    def seed_shape(self, state: State) -> None:
        _thermal_seed(state, self.mesh, self.cfg, self.solver, self.seed_info)

    def fail(self, msg: str, X):
        """Write failure.nc, close the progress output and raise NumericalInstability."""
        state, path = self.state, self.outdir / FAILURE
        write_failure(path, self.be.asnumpy(X),
                      {"message": msg, "step": state.step, "t_tau": state.t, "dt": self.dt, "phase": state.phase})
        self.bar.close()
        raise NumericalInstability(f"{msg} (step {state.step}, t = {state.t:.6g} tau); state written to {path}")

    def loop(self, stop_after_steps: int | None) -> bool:
        """Step until the end of the run (-> True) or until ``stop_after_steps`` steps of this call (-> False)."""
        state, cfg = self.state, self.cfg
        while True:
            done, output_due = self._events()
            X = state.X  # the reversal may have seeded the shape
            F, geo = self.solver.forces(X)
            if output_due:
                self._output(X, geo)
            rate = cfg.chi * (1.0 if state.phase == "stretch" else -1.0)
            if done:
                if cfg.store_velocity:  # the velocity at the last frame: one step computed, not taken
                    dt_last = self.dt_step if self.dt_step > 0 else self.dt
                    dX = self.integ.step(state, X, F, geo, dt_last, rate)
                    self.writer.set_velocity(self.be.asnumpy(dX) / dt_last)
                return True
            t_event = self._step_length(X, geo, output_due)
            self._advance(X, F, geo, rate, output_due, t_event)
            if self.stop_signal:  # SIGINT/SIGTERM during the step: keep it, then stop
                self.checkpoint()
                log.warning("stopped by signal %d at step %d (t = %.6g tau); checkpoint written, rerun the same "
                            "command to resume", self.stop_signal, state.step, state.t)
                raise KeyboardInterrupt
            if stop_after_steps is not None and self.steps_this_call >= stop_after_steps:
                return False

    def _events(self) -> tuple[bool, bool]:
        """Reverse the flow when the stretching phase is over; -> (the run is done, a frame is due) at this step."""
        state, cfg, T, eps_t = self.state, self.cfg, self.T, self.eps_t
        if self.adaptive:
            if state.phase == "stretch" and state.t >= self.t_stretch_end - eps_t:
                _reverse(state, self.bar, None, cfg, stationary=False, on_reverse=self.seed_shape)
                state.next_output_t = state.t
            done = state.phase == "relax" and state.t >= state.t_reverse + cfg.t_end * T - eps_t
            if done:
                state.next_output_t = state.t
            return done, state.t >= state.next_output_t - eps_t
        # phase changes depend on the step count only, so a resumed run takes them at the same steps
        if state.phase == "stretch" and state.step >= self.stretch_steps:
            _reverse(state, self.bar, self.relax_steps, cfg, stationary=False, on_reverse=self.seed_shape)
            state.next_output = state.step  # a frame at t0 exactly; later frames every output_every
        done = state.phase == "relax" and state.t - state.t_reverse >= cfg.t_end * T - 0.5 * self.dt
        if done:
            state.next_output = state.step  # the last frame is always written
        return done, state.step == state.next_output

    def _next_frame_time(self) -> float:
        state = self.state
        base = state.t_reverse if state.phase == "relax" else 0.0
        k = math.floor((state.t - base) / self.t_out + 0.5)
        return base + (k + 1) * self.t_out

    def _output(self, X, geo) -> None:
        """Write the frame at X, schedule the next one, report progress, and reverse early once the stretched
        shape is stationary."""
        state, cfg = self.state, self.cfg
        sc = self._frame(X, geo)
        state.next_output = state.step + self.out_steps
        state.next_output_t = self._next_frame_time()
        self._report(sc)
        if state.phase == "stretch" and cfg.stationary_tol > 0 and state.step > 0:
            mom = _shape_moments(X, self.xp)
            rate = max(abs(a - b) / b for a, b in zip(mom, state.shape_prev, strict=True)) / cfg.output_every
            state.shape_prev = mom
            if rate < cfg.stationary_tol:  # the frame just written is the one at t0
                _reverse(state, self.bar, None if self.adaptive else self.relax_steps, cfg, stationary=True)
                state.next_output_t = self._next_frame_time()

    def _frame(self, X, geo) -> dict:
        """Append the frame at X to the trajectory after the NaN and drift checks; -> its scalars."""
        state, cfg, mem, A0, V0 = self.state, self.cfg, self.mem, self.A0, self.V0
        sig_l = self.integ.face_tension(state, geo)
        A = to_float(geo.area.sum())
        V = B.volume(X, mem.topo, geo)
        sig = B.global_tension(geo, sig_l) + (cfg.K_area * (A - A0) / A0 if cfg.K_area else 0.0)
        flow_sign = 1.0 if state.phase == "stretch" else -1.0
        sc = {"t_tau": state.t, "tension": sig, "area": A, "volume": V, "area_drift": A / A0 - 1,
              "volume_drift": V / V0 - 1,
              "bending_energy": B.bending_energy(X, mem.topo, mem.kappa, geo, mem.area_model),
              "tension_energy": B.tension_energy(geo, mem.ref, mem.Lambda), "flow_sign": flow_sign}
        if not all(math.isfinite(v) for v in sc.values()):
            self.fail("non-finite energy or tension", X)
        if abs(sc["area_drift"]) > cfg.max_drift or abs(sc["volume_drift"]) > cfg.max_drift:
            self.fail(f"area drift {sc['area_drift']:.3%} or volume drift {sc['volume_drift']:.3%} exceeds "
                      f"max_drift = {cfg.max_drift:g}; lower dt or raise Lambda", X)
        sc.update(dt_tau=self.dt_step, cg_iterations=float(state.cg_iterations[-1]) if state.cg_iterations else 0.0)
        q = B.triangle_quality(geo)  # 4 sqrt(3) A / sum l^2, and the triangle strain against the reference mesh
        ref = mem.ref.face_area if state.lipid_area is None else self.xp.asarray(state.lipid_area)
        strain = self.xp.abs(geo.area / ref - 1).max()
        sc.update(mesh_quality_min=to_float(q.min()), mesh_quality_median=to_float(self.xp.median(q)),
                  triangle_strain_max=to_float(strain), **step_limits.frame_scalars(state))
        self.writer.append(self.be.asnumpy(X), self.be.asnumpy(sig_l).astype(np.float32), sc)
        state.n_frames += 1
        return sc

    def _report(self, sc: dict) -> None:
        state, cfg, dt_step = self.state, self.cfg, self.dt_step
        t_show = cfg.chi * (state.t - state.t_reverse) if state.phase == "relax" else cfg.chi * state.t
        info = f"{state.phase} gt={t_show:.3f} sigma={sc['tension']:.4g} dA={sc['area_drift']:.1e}"
        if not self.adaptive:
            self.bar.update(state.step, info)
            return
        info = f"step {state.step} {info} dt={dt_step:.2e} cg={sc['cg_iterations']:.0f}"
        T_all = (cfg.stretch + cfg.t_end) * self.T
        t_done = state.t if state.phase == "stretch" else self.t_stretch_end + state.t - state.t_reverse
        self.bar.update(min(1000, int(1000 * t_done / max(T_all, 1e-300))), info)

    def _step_length(self, X, geo, at_frame: bool = False) -> float | None:
        """Set ``dt_step``, the next step's length from X (a frame if ``at_frame``); -> its event's time (adaptive)."""
        state, cfg, T = self.state, self.cfg, self.T
        if not self.adaptive:
            self.dt_step = self.dt
            step_limits.record(state, {"fixed": self.dt}, "fixed")
            return None
        # land exactly on the next frame, the reversal or the end, in equal steps
        t_event = min(state.next_output_t,
                      self.t_stretch_end if state.phase == "stretch" else state.t_reverse + cfg.t_end * T)
        dt_want = self.integ.next_dt(state, geo)
        if not dt_want > DT_COLLAPSE * self.dt:
            # a healthy run stays within ~1e-2 of the bending limit; the elongated vesicle at 256^3 crept on at
            # 3e-12 tau per step for 700 steps with a folded mesh (tension 1e8) before this bound existed
            self.fail(f"time step collapsed to {dt_want:.3g} tau, {dt_want / self.dt:.2g} x the bending limit "
                      f"{self.dt:.3g} tau (set by the {self.integ.binding_limit} limit)", X)
        remaining = t_event - state.t
        # the frame sets the step only when closer than every limit from the frame before, not in the equal pieces
        step_limits.record(state, self.integ.limits, self.integ.binding_limit, remaining if at_frame else math.inf)
        self.dt_step = remaining / max(1, math.ceil(remaining / dt_want - 1e-6))
        return t_event

    def _advance(self, X, F, geo, rate: float, output_due: bool, t_event: float | None) -> None:
        """Take the step from X (eq. 29 or the scheme's), store the frame's velocity, check, checkpoint."""
        state, cfg, dt_step = self.state, self.cfg, self.dt_step
        dX = self.integ.step(state, X, F, geo, dt_step, rate)
        dt_step = self.dt_step = self.integ.taken(dt_step)  # shorter where an error controller rejected the step
        if output_due and cfg.store_velocity:
            self.writer.set_velocity(self.be.asnumpy(dX) / dt_step)
        state.X = X + dX
        state.step += 1
        state.t = state.t + dt_step
        if self.adaptive and abs(state.t - t_event) < self.eps_t:
            state.t = t_event
        self.steps_this_call += 1
        if state.step % 16 == 0 and not bool(to_numpy(self.xp.isfinite(state.X).all())):
            self.fail("NaN or Inf in vertex positions (time step too large?)", X)
        if state.step % cfg.checkpoint_every == 0 or _time.perf_counter() - self.last_checkpoint >= CHECKPOINT_WALL_S:
            self.checkpoint()

    def checkpoint(self) -> None:
        # a checkpoint counts the frames on disk: with frames still in memory (the file held by a reader) a resume
        # would find fewer than it claims, so skip this one and keep the last
        if not self.writer.flush(wait_s=5.0):
            return
        u_hat = self.solver.stokes.state["u_hat"] if self.cfg.rho_bar > 0 else None
        wall0 = self.state.wall_s
        self.state.wall_s = wall0 + (_time.perf_counter() - self.wall0)  # the run's wall time up to this step
        try:
            save_checkpoint(self.outdir / CHECKPOINT, self.state, self.be, u_hat)
        finally:
            self.state.wall_s = wall0
        self.last_checkpoint = _time.perf_counter()

    def finalize(self) -> Path:
        """Move the complete trajectory to trajectory.nc with the run's statistics; drop the checkpoint."""
        state, cfg = self.state, self.cfg
        wall = _time.perf_counter() - self.wall0
        extra = {**self.integ.stats(), **self.seed_info, "steps": state.step, "wall_time_s_last_call": wall,
                 "wall_time_s": state.wall_s + wall,  # all calls; NaN if an earlier call did not record it
                 "t_reverse_tau": state.t_reverse, "t_reverse_gamma": state.t_reverse * cfg.chi,
                 "resumed": int(self.resumed)}
        if self.adaptive and state.step > 0:  # the mean step (each frame stores its own in dt_tau)
            extra.update(dt_tau=state.t / state.step, dt_gamma=cfg.chi * state.t / state.step, dt_bending_tau=self.dt)
        path = self.writer.finalize(state.t_reverse, cfg.chi, extra)
        (self.outdir / CHECKPOINT).unlink(missing_ok=True)
        return path


def _catch_stop_signals(r: _Run) -> dict:
    """SIGINT and SIGTERM (Ctrl-C, a scheduler's or Snakemake's stop) end the run after the current step with a
    checkpoint, so a long run loses at most one step; a second signal stops at once. -> the previous handlers."""
    import threading

    if threading.current_thread() is not threading.main_thread():  # signal handlers live in the main thread
        return {}

    def handler(signum, frame):
        if r.stop_signal:
            raise KeyboardInterrupt
        r.stop_signal = signum
        log.warning("signal %d: stopping after this step with a checkpoint (send it again to stop at once)", signum)

    return {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}


def run(mesh, cfg: RunConfig, outdir, progress: bool = True, stop_after_steps: int | None = None) -> Path:
    """Run (or resume) one case; returns the path of the complete trajectory, or None when ``stop_after_steps``
    ended it early as if interrupted (the resume test)."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    with hold_run_lock(outdir):  # before anything in the directory is touched; released however the run ends
        return _run_locked(mesh, cfg, outdir, progress, stop_after_steps)


def _run_locked(mesh, cfg, outdir, progress, stop_after_steps):
    (outdir / FAILURE).unlink(missing_ok=True)
    mesh.check()
    r = _Run(mesh, cfg, outdir, progress)
    previous = _catch_stop_signals(r)
    try:
        finished = r.loop(stop_after_steps)
    except NumericalInstability as exc:
        if not (outdir / FAILURE).exists():  # raised inside a solve (e.g. CG did not converge)
            r.fail(str(exc), r.state.X)
        raise
    except KeyboardInterrupt:
        r.bar.close()
        if not r.stop_signal:
            log.warning("interrupted at step %d; rerun the same command to resume from the last checkpoint",
                        r.state.step)
        raise
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    r.bar.close()
    return r.finalize() if finished else None
