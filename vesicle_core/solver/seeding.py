"""Wrinkle seeds at the flow reversal: the thermal spectrum the perturbation analysis starts from, put on the IBM shape.

Without a seed the IBM's wrinkles grow from mesh noise (Delta_l ~ 1e-5 at the reversal), as in the paper's IBM,
which has no thermal noise. The PA (``theory.initial_state``) instead starts from the thermal spectrum of Sec. V.A,
<|u_lm|^2> = 2 k_B T / (kappa (l^4 + S l^2 / A_2)) on the scaled amplitudes u_lm of eq. (30). To compare the two
from the same start, :func:`thermal_seed` adds exactly that spectrum (the same draw, ``theory.initial_state`` with
the same seed) for 3 <= l <= l_max to the shape, as a radial displacement about the volume centroid:

    r -> r (1 + sum_{l >= 3, m} c_lm Y_lm),   c_lm = u_lm / sqrt((l - 1)(l + 2) / Delta)   (eq. 30)

The l = 2 part is left to the stretch: it is the flow's own deformation. ``scale`` multiplies the thermal energy
k_B T (so the variance; amplitudes grow by sqrt(scale)). l_max is the PA's default truncation, capped at what the
mesh resolves (``surface.resolvable_l_max``), since finer modes would alias into mesh noise.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError, check_range

#: run-key values of ``seed_spectrum``
SEED_SPECTRA = ("mesh", "thermal")


def thermal_coefficients(delta, S, *, l_max, seed=0, scale=1.0, l_min=3):
    """Coefficients c_lm of the relative radial displacement (harmonics layout, index [l, l_max + m]).

    The PA's initial draw (``theory.initial_state`` at the same seed, with the default thermal spectrum), rescaled
    from u_lm to the unscaled c_lm of eq. (30), zero below l_min, amplitudes times sqrt(scale).
    """
    from ..model.modes import initial_state

    check_range("delta", delta, 0.0, None, lo_open=True)
    check_range("S", S, 0.0, None)
    check_range("scale", scale, 0.0, 1e6)
    check_range("l_min", l_min, 2, None, integer=True)
    u = initial_state(int(l_max), float(S), delta=float(delta), seed=int(seed))
    l = np.arange(u.shape[0], dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.where(l >= 2, np.sqrt((l - 1.0) * (l + 2.0) / float(delta)), np.inf)
    c = u / factor[:, None]
    c[: int(l_min)] = 0.0
    return c * np.sqrt(float(scale))


def thermal_seed(vertices, faces, *, delta, S, seed=0, scale=1.0, l_max=None):
    """Vertices displaced radially by the PA's initial thermal spectrum (module docstring); returns (X, l_max)."""
    from ..geometry import surface as Sf
    from ..geometry import ylm as Yl
    from ..model.modes import default_l_max

    X = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    l_res = Sf.resolvable_l_max(X, f)
    if l_max is None:
        l_max = min(default_l_max(float(S)), l_res)
    if l_max < 3:
        raise ConfigError(f"the mesh resolves l <= {l_res}; a thermal seed needs l_max >= 3")
    c = thermal_coefficients(delta, S, l_max=l_max, seed=seed, scale=scale)
    center = Sf.volume_centroid(X, f)
    rel = X - center
    r = np.linalg.norm(rel, axis=1)
    theta = np.arccos(np.clip(rel[:, 2] / r, -1.0, 1.0))
    phi = np.arctan2(rel[:, 1], rel[:, 0])
    return center + rel * (1.0 + Yl.synthesize(c, theta, phi))[:, None], int(l_max)
