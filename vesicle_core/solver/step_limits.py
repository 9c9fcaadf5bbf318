"""Which limit sets each time step, recorded per frame of a trajectory.

An adaptive run (the inextensible scheme) takes each step as the smallest of several limits
(:meth:`vesicle_core.solver.integrators.Inextensible.next_dt`): the bending stability limit (Arnoldi, step_size), the
tension's stability, the growth limit (``dt_growth`` e-folds of the fastest wrinkle), the flow's strain per step, the
linearised constraint's strain (``dt_strain``) and the noise's displacement per step (``noise_step``); with
``step_control: error`` the error controller's step (``error``) replaces the growth and flow limits, and a step the
controller rejected and retried shorter counts under ``error`` (:func:`rejected`). A fixed-step run
has one limit, ``fixed``. The step actually taken can be a little shorter than the binding limit allows: it lands
on the next frame, the reversal or the end in equal steps (simulate); the limit recorded is the one that set the
step count, the argmin of the allowed steps, and ``event`` where the time left to that frame, reversal or end is
shorter than every limit (one step to it).

Each frame records the limit of the last step before it (``step_limit``, a CF flag variable), the step that every
limit allowed for that step (``dt_limit_<name>``, NaN where a limit did not apply) and how many steps each limit set
since the previous frame (``steps_<name>``), so that the shares of a run are exact counts: summed over the frames
they give the run's step count. The record lives on the run's State (checkpointed), so a resumed run counts what an
uninterrupted one does. Nothing here enters the arithmetic of a step.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["LIMITS", "frame_scalars", "frame_variables", "record", "rejected", "shares_line"]

#: every limit a step can be set by, in the order of its flag value (0, 1, ...); -1: no step yet
LIMITS = ("fixed", "bending", "tension", "growth", "flow", "strain", "noise_step", "event", "error")

_MEANING = {
    "fixed": "the fixed step of a non-adaptive run (dt given, or the explicit and projection schemes)",
    "bending": "dt_safety x the bending stability limit 2 / |lam|max (Arnoldi, re-measured every 20 steps)",
    "tension": "dt_safety x the tension's stability limit, TENSION_STABILITY h / max |sigma|",
    "growth": "dt_growth e-folds of the fastest-growing wrinkle mode (eq. 11)",
    "flow": "the background flow's strain per step, 0.1 dt_growth / chi",
    "strain": "the linearised area constraint's second-order strain per step (dt_strain)",
    "noise_step": "the thermal noise's rms displacement per step (noise_step h)",
    "event": "the time left to the next frame, the reversal or the end, where that is shorter than every limit",
    "error": "step_control error: the step the error controller wants (embedded_midpoint; it replaces growth and "
             "flow), or the retry of a rejected step",
}


def _empty_counts() -> list:
    return [0] * len(LIMITS)


def record(state, limits: dict, binding: str, until_event: float = math.inf) -> None:
    """Note on ``state`` that the next step is set by ``binding``, with the step every limit allowed (``limits``:
    name -> dt in tau, only the limits that applied). ``until_event``: the time left to the next frame, reversal
    or end (adaptive runs); where it is shorter than every limit, the step is one step to it, set by ``event``."""
    if until_event < limits[binding]:
        limits, binding = {**limits, "event": until_event}, "event"
    unknown = set(limits) - set(LIMITS)
    if unknown or binding not in limits:
        raise ValueError(f"unknown step limit(s) {sorted(unknown | ({binding} - set(limits)))}; known: {LIMITS}")
    if state.limit_counts is None:
        state.limit_counts = _empty_counts()
    code = LIMITS.index(binding)
    state.limit_counts[code] += 1
    state.limit_last = code
    # a limit that allows any step (noise_step without noise) did not apply
    state.limit_dt = [float(dt) if math.isfinite(dt := limits.get(name, math.nan)) else math.nan for name in LIMITS]


def rejected(state, dt: float) -> None:
    """The step just recorded was rejected by the error controller (step_control error) and is retried at ``dt``:
    the step counts as set by the ``error`` limit, which allowed ``dt``; the other limits' allowed steps stay."""
    if state.limit_counts is None:  # a step taken outside the driver's record
        return
    error = LIMITS.index("error")
    state.limit_counts[state.limit_last] -= 1
    state.limit_counts[error] += 1
    state.limit_last = error
    state.limit_dt[error] = float(dt)


def frame_scalars(state) -> dict:
    """The frame's record (``step_limit``, ``dt_limit_<name>``, ``steps_<name>``) and a fresh count for the steps
    to the next frame."""
    counts = state.limit_counts or _empty_counts()
    dts = state.limit_dt or [math.nan] * len(LIMITS)
    out = {"step_limit": state.limit_last}
    out.update({f"dt_limit_{name}": dt for name, dt in zip(LIMITS, dts, strict=True)})
    out.update({f"steps_{name}": n for name, n in zip(LIMITS, counts, strict=True)})
    state.limit_counts = _empty_counts()
    return out


def frame_variables() -> dict:
    """name -> (netCDF type, attributes) of the per-frame record, in the trajectory's order."""
    out = {"step_limit": ("i1", {
        "long_name": "the limit that set the last step before this frame",
        "flag_values": np.arange(-1, len(LIMITS), dtype=np.int8),
        "flag_meanings": " ".join(("none", *LIMITS))})}
    for name in LIMITS:
        out[f"dt_limit_{name}"] = ("f8", {"units": "tau", "long_name": (
            f"the step the {name} limit allowed for the last step before this frame (NaN: not applied): "
            f"{_MEANING[name]}")})
    for name in LIMITS:
        out[f"steps_{name}"] = ("i4", {"units": "1", "long_name": f"steps set by the {name} limit since the "
                                       "previous frame"})
    return out


def shares_line(counts: dict) -> str:
    """``steps: 569 (bending 71%, growth 20%, flow 9%)`` from name -> steps, largest share first."""
    total = sum(counts.values())
    parts = [f"{name} {100 * n / total:.0f}%" for name, n in sorted(counts.items(), key=lambda kv: -kv[1]) if n > 0]
    return f"steps: {total}" + (f" ({', '.join(parts)})" if parts else "")
