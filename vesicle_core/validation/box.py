"""The periodic-box test (Table I): the same case in two box sizes, their shape and velocity differences, and the
membrane tension's extrapolation to an unbounded fluid through the periodic images' 1/L^3 law."""

from __future__ import annotations

import math

import numpy as np


def _positions(ds, i):
    return np.stack([ds[c].values[i] for c in ("node_x", "node_y", "node_z")], axis=1)


def _induced_velocity(ds, i):
    """The stored membrane velocity of frame i less the background flow u_inf(X) = rate (x, -y, 0)."""
    from ..model.flow import background_velocity

    X = _positions(ds, i)
    U = np.stack([ds[c].values[i] for c in ("node_ux", "node_uy", "node_uz")], axis=1)
    rate = float(ds.attrs["chi"]) * float(ds["flow_sign"].values[i])
    return U - background_velocity(X, rate)


def box_tension(traj) -> float:
    """The mean membrane tension at the flow reversal (the last stretch frame, time 0) [kappa/R^2]."""
    t = traj["time"].values
    return float(traj["tension"].values[int(np.argmin(np.abs(t)))])


def image_extrapolation(L_small, y_small, L_large, y_large) -> float:
    """y at L -> infinity from two boxes with y(L) = y_inf + c / L^3.

    The periodic images of a force-free vesicle interact through its stresslet, whose image sum scales with the
    volume fraction ~ 1/L^3 (the same law as the l = 2 relaxation rate's box correction in docs/history/solver.md).
    """
    a, b = L_small**-3, L_large**-3
    if not abs(a - b) > 0:
        return math.nan  # one box size: nothing to extrapolate from
    return float((y_large * a - y_small * b) / (a - b))


def box_comparison(traj_small, traj_large) -> dict:
    """Table I: maximum relative difference of the membrane shape and velocity between two box sizes.

    Frames are matched by time. The velocity is the stored one (``store_velocity``) less the background flow, i.e.
    the induced velocity u_ind of Table I; runs without stored velocities fall back to centred differences of
    consecutive frames (total velocity). Errors are max_k |a_k - b_k| / max_k |a_k| per frame, then the maximum
    over frames (shape) and the median and maximum over frames (velocity, whose small-|u| frames inflate the
    ratio, as the paper notes).
    """
    ta = traj_small["time"].values
    tb = traj_large["time"].values
    common = np.intersect1d(np.round(ta, 9), np.round(tb, 9))
    if len(common) < 3:
        raise ValueError("the two box runs share fewer than 3 output times: run both with the same output_every")
    stored = all(v in ds for ds in (traj_small, traj_large) for v in ("node_ux", "node_uy", "node_uz"))

    def index(ds, t):
        return int(np.argmin(np.abs(ds["time"].values - t)))

    shape_err, vel_err, times = [], [], []
    shape_t = []
    for k, t in enumerate(common):
        ia, ib = index(traj_small, t), index(traj_large, t)
        xa, xb = _positions(traj_small, ia), _positions(traj_large, ib)
        shape_err.append(np.linalg.norm(xa - xb, axis=1).max() / np.linalg.norm(xa, axis=1).max())
        shape_t.append(float(t))
        if stored:
            ua, ub = _induced_velocity(traj_small, ia), _induced_velocity(traj_large, ib)
        elif 0 < k < len(common) - 1:
            dt = common[k + 1] - common[k - 1]
            ua = (_positions(traj_small, index(traj_small, common[k + 1]))
                  - _positions(traj_small, index(traj_small, common[k - 1]))) / dt
            ub = (_positions(traj_large, index(traj_large, common[k + 1]))
                  - _positions(traj_large, index(traj_large, common[k - 1]))) / dt
        else:
            continue
        vel_err.append(np.linalg.norm(ua - ub, axis=1).max() / max(np.linalg.norm(ua, axis=1).max(), 1e-300))
        times.append(float(t))
    s_small, s_large = box_tension(traj_small), box_tension(traj_large)
    L_s, L_l = float(traj_small.attrs.get("L", math.nan)), float(traj_large.attrs.get("L", math.nan))
    return {"L_small": L_s, "L_large": L_l,
            "tension_small": s_small, "tension_large": s_large,
            "tension_unbounded": image_extrapolation(L_s, s_small, L_l, s_large),
            "N_small": int(traj_small.attrs.get("N", -1)), "N_large": int(traj_large.attrs.get("N", -1)),
            "max_shape_error": float(np.max(shape_err)), "max_velocity_error": float(np.max(vel_err)),
            "median_velocity_error": float(np.median(vel_err)), "frames": int(len(common)),
            "velocity": "stored, induced part" if stored else "frame differences, total",
            "final_shape_error": float(shape_err[-1]),
            "t_max_shape_error": shape_t[int(np.argmax(shape_err))], "reversal_shape_error":
                float(shape_err[int(np.argmin(np.abs(np.array(shape_t))))])}
