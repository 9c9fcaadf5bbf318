"""Background elongational flow u_inf of Sec. II B and Fig. 1, evaluated at the membrane vertices.

u_inf = gamma_dot (x, -y, 0) before the reversal at t_0 and -gamma_dot (x, -y, 0) after (Fig. 1).
In internal units (time in tau = mu R^3 / kappa) gamma_dot = chi. The background flow is not
periodic, so, as in eq. (29), it is evaluated directly at the (moving) Lagrangian positions X_k^n and
never put on the periodic grid: X^{n+1} = X^n + J Gamma^n + u_inf(X^n) dt.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError


def flow_sign(t, t_reverse=None):
    """+1 before the reversal, -1 from t_reverse on (S(t) = -S sign(t - t_0), Fig. 1).

    t_reverse None (or +inf) means the flow is never reversed. Works elementwise on arrays.
    """
    if t_reverse is None:
        return np.ones_like(np.asarray(t, dtype=float)) if np.ndim(t) else 1.0
    s = np.where(np.asarray(t, dtype=float) < float(t_reverse), 1.0, -1.0)
    return s if np.ndim(t) else float(s)


def rate_at(t, chi, t_reverse=None):
    """Signed extensional rate gamma_dot(t) = chi * flow_sign(t, t_reverse) (units 1/tau)."""
    return chi * flow_sign(t, t_reverse)


def background_velocity(X, rate):
    """u_inf(X) = rate * (x, -y, 0) at the positions X (M, 3); returns a new (M, 3) array.

    ``rate`` is the signed rate of :func:`rate_at`. Works for NumPy and CuPy arrays alike (only
    array methods are used, so the result lives on the same device as X).
    """
    if not hasattr(X, "ndim"):
        X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3:
        raise ConfigError(f"X must have shape (M, 3), got {tuple(X.shape)}")
    u = X.astype(X.dtype if X.dtype.kind == "f" else np.float64, copy=True)
    u[:, 0] *= rate
    u[:, 1] *= -rate
    u[:, 2] = 0
    return u
