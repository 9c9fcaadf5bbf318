"""The regularised Stokeslet that a coupling makes, against the periodic Oseen and Rotne-Prager-Yamakawa tensors.

A point force spread with a kernel, solved on the periodic grid and interpolated back gives the coupling's pair
mobility M(x, y) (:class:`~vesicle_core.solver.mobility.IBMMobility`, two markers). This module measures what it is, per
kernel and coupling (``kernel``, or ``sharp``: the window deconvolution of :mod:`vesicle_core.solver.kernels`):

* the self-mobility M(x, x) and its hydrodynamic radius a_h = 1 / (6 pi mu M_free), after Hasimoto's periodic
  correction M_per = M_free (1 - 2.837297 a_h / L) (to first order in a_h / L);
* the translation invariance: the relative spread of the self- and pair mobility when the same configuration is
  shifted by random sub-grid offsets (an exact continuum operator would not move; 3.3e-3 for the 4-point kernel);
* the pair mobility at 2-10 h against the periodic Oseen tensor (Hasimoto's Ewald sum, :func:`periodic_oseen`) and
  the Rotne-Prager-Yamakawa tensor of radius a_h (its free-space finite-size term added to the periodic Oseen one).

Units: mu = 1, lengths in the grid's unit (R); velocities per unit force.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Hasimoto's constant: the periodic self-mobility of a sphere of radius a in a cubic box of edge L is
#: (1 - HASIMOTO a / L + ...) / (6 pi mu a)
HASIMOTO = 2.837297


def periodic_oseen(x, F, L, xi=None):
    """Velocity at separations x (n, 3) of a point force F (3,) and its periodic images, zero mean (mu = 1).

    Hasimoto's Ewald split (Beenakker 1986, point-force limit): u = 1/(8 pi) [sum_n M_R(x + n L) +
    L^-3 sum_{k != 0} M_F(k) e^{i k.x}] F with M_R = (erfc(a) + 2a/sqrt(pi) (2a^2 - 3) e^{-a^2}) I/r +
    (erfc(a) + 2a/sqrt(pi) (1 - 2a^2) e^{-a^2}) rr/r^3, a = xi r, and M_F = 8 pi/k^2 (1 + k^2/4xi^2 + k^4/8xi^4)
    e^{-k^2/4xi^2} (I - kk/k^2). The zero mean is the grid solver's k = 0 convention. ``xi`` defaults to 3/L;
    images beyond |n| = 1 and wave numbers beyond e^{-k^2/4xi^2} ~ e^{-10} are dropped (~1e-10 relative).
    """
    from scipy.special import erfc

    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    F = np.asarray(F, dtype=np.float64)
    xi = 3.0 / L if xi is None else float(xi)
    u = np.zeros((len(x), 3))
    rng = np.arange(-1, 2)
    for n in np.stack(np.meshgrid(rng, rng, rng, indexing="ij"), -1).reshape(-1, 3):
        r = x + n * L
        rr = np.linalg.norm(r, axis=1)
        a = xi * rr
        e = np.exp(-(a**2))
        C = (erfc(a) + 2 * a / np.sqrt(np.pi) * (2 * a * a - 3) * e) / rr
        D = (erfc(a) + 2 * a / np.sqrt(np.pi) * (1 - 2 * a * a) * e) / rr**3
        u += C[:, None] * F + D[:, None] * r * (r @ F)[:, None]
    mmax = int(np.ceil(np.sqrt(40.0) * xi * L / np.pi)) + 1
    m = np.arange(-mmax, mmax + 1)
    K = np.stack(np.meshgrid(m, m, m, indexing="ij"), -1).reshape(-1, 3) * (2 * np.pi / L)
    K = K[np.any(K != 0, axis=1)]
    k2 = (K**2).sum(1)
    w = 8 * np.pi / k2 * (1 + k2 / (4 * xi**2) + k2**2 / (8 * xi**4)) * np.exp(-k2 / (4 * xi**2))
    PF = F[None, :] - K * ((K @ F) / k2)[:, None]
    u += (np.cos(x @ K.T) * w[None, :]) @ PF / L**3
    return u / (8 * np.pi)


def rpy_correction(x, F, a):
    """The Rotne-Prager-Yamakawa tensor minus the Oseen tensor (free space, r >= 2a, mu = 1) applied to F:
    a^2 / (8 pi r^3) [(2/3) I - 2 r_hat r_hat] F, the finite-size term (a^2/6) lap G. Added to
    :func:`periodic_oseen`, it is the periodic RPY tensor up to the images' own a^2 / L^3 terms."""
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    r = np.linalg.norm(x, axis=1)
    rh = x / r[:, None]
    c = a * a / (8 * np.pi * r**3)
    return c[:, None] * ((2.0 / 3.0) * F[None, :] - 2.0 * rh * (rh @ F)[:, None])


def _mobility(N, L, kernel, coupling, sharp_floor, backend="numpy"):
    from ..solver.backend import get_backend
    from ..solver.ibm import Coupler, Grid
    from ..solver.kernels import sharpening_symbol
    from ..solver.mobility import IBMMobility
    from ..solver.stokes import StokesSolver

    grid, be = Grid(N, L), get_backend(backend)
    filt = sharpening_symbol(N, kernel, sharp_floor) if coupling == "sharp" else None
    return IBMMobility(Coupler(grid, be, kernel=kernel), StokesSolver(grid, be, force_filter=filt))


@dataclass(frozen=True)
class StokesletReport:
    """What a coupling's regularised Stokeslet is, on one grid (see the module docstring); lengths in h."""

    kernel: str
    coupling: str
    sharp_floor: float | None
    N: int
    self_mobility: float  # mean over sub-grid positions, 1/mu in grid units (R)
    a_h: float  # hydrodynamic radius / h, Hasimoto-corrected
    self_spread: float  # std / mean of the self-mobility over sub-grid positions
    pair_spread: float  # max over distances of std / mean of the pair mobility's trace over sub-grid shifts
    r: tuple  # pair distances / h
    oseen_error: tuple  # |M_pair F - periodic Oseen F| / (|F| / (8 pi mu r)), mean over positions and directions
    rpy_error: tuple  # the same against periodic Oseen + the RPY finite-size term with a_h


def stokeslet_report(kernel="peskin4", coupling="kernel", sharp_floor=0.01, N=64, L=None, r=(2, 3, 4, 6, 8, 10),
                     n_positions=12, seed=0) -> StokesletReport:
    """Measure the coupling's self- and pair mobility (``n_positions`` random sub-grid origins and directions, one
    Stokes solve each). ``L`` defaults to N h with h = 1, so distances are in h directly."""
    L = float(N) if L is None else float(L)
    mob = _mobility(N, L, kernel, coupling, sharp_floor)
    h = L / N
    rng = np.random.default_rng(seed)
    r = np.asarray(r, dtype=float)
    selfs, traces, eo, er = [], [], [], []
    pos = []
    for _ in range(n_positions):
        x0 = L / 2 + rng.uniform(0.0, h, 3)
        d = rng.standard_normal(3)
        d /= np.linalg.norm(d)
        F = rng.standard_normal(3)
        F /= np.linalg.norm(F)
        X = np.vstack([x0[None, :], x0[None, :] + h * r[:, None] * d[None, :]])
        Fm = np.zeros_like(X)
        Fm[0] = F
        mob.prepare(mob.backend.xp.asarray(X))
        U = mob.backend.asnumpy(mob.apply(mob.backend.xp.asarray(Fm)))
        selfs.append(float(U[0] @ F))
        sep = h * r[:, None] * d[None, :]
        pos.append((U[1:], sep, F))
    m0 = float(np.mean(selfs))
    # free-space self-mobility from the periodic one (Hasimoto, first order): m_per = m_free (1 - c a / L)
    a_free = 1.0 / (6 * np.pi * m0)
    for _ in range(3):  # fixed point of a = 1 / (6 pi m_free), m_free = m0 / (1 - c a / L)
        a_free = (1.0 - HASIMOTO * a_free / L) / (6 * np.pi * m0)
    for Up, sep, F in pos:
        Uo = periodic_oseen(sep, F, L)
        Ur = Uo + rpy_correction(sep, F, a_free)
        scale = 1.0 / (8 * np.pi * h * r)  # |F| / (8 pi mu r): the Stokeslet's size, as the grid tests measure it
        eo.append(np.linalg.norm(Up - Uo, axis=1) / scale)
        er.append(np.linalg.norm(Up - Ur, axis=1) / scale)
        traces.append(np.einsum("ij,j->i", Up, F))
    spread = _pair_spread(mob, r, h, L, rng)
    return StokesletReport(kernel, coupling, sharp_floor if coupling == "sharp" else None, N, m0, a_free / h,
                           float(np.std(selfs) / m0), spread, tuple(float(x) for x in r),
                           tuple(float(x) for x in np.mean(eo, 0)), tuple(float(x) for x in np.mean(er, 0)))


def _pair_spread(mob, r, h, L, rng, n_shifts=8):
    """Relative std of F . M(x + s, y + s) F over random sub-grid shifts s of one fixed pair geometry, the largest
    over the distances r: the translation invariance of the pair mobility."""
    d = np.array([0.48, 0.36, 0.8])
    d /= np.linalg.norm(d)
    F = np.array([0.6, -0.64, 0.48])
    vals = []
    for _ in range(n_shifts):
        x0 = L / 2 + rng.uniform(0.0, h, 3)
        X = np.vstack([x0[None, :], x0[None, :] + h * r[:, None] * d[None, :]])
        Fm = np.zeros_like(X)
        Fm[0] = F
        mob.prepare(mob.backend.xp.asarray(X))
        U = mob.backend.asnumpy(mob.apply(mob.backend.xp.asarray(Fm)))
        vals.append(U[1:] @ F)
    vals = np.array(vals)
    return float(np.max(np.std(vals, 0) / np.abs(np.mean(vals, 0))))


def hydrodynamic_radius(kernel="peskin4", coupling="kernel", sharp_floor=0.01, N=64, n_positions=12, seed=0):
    """a_h / h of the coupling (Hasimoto-corrected self-mobility, mean over sub-grid positions)."""
    return stokeslet_report(kernel, coupling, sharp_floor, N=N, r=(4,), n_positions=n_positions, seed=seed).a_h


def fmt_report(rep: StokesletReport) -> str:
    """One line per report for benchmarks and logs."""
    fl = "" if rep.sharp_floor is None else f" floor {rep.sharp_floor:g}"
    errs = " ".join(f"{e:.3f}" for e in rep.oseen_error)
    rpy = " ".join(f"{e:.3f}" for e in rep.rpy_error)
    return (f"{rep.kernel} {rep.coupling}{fl}: a_h {rep.a_h:.3f} h, self spread {rep.self_spread:.2e}, "
            f"pair spread {rep.pair_spread:.2e}; vs Oseen at r/h {list(rep.r)}: {errs}; vs RPY: {rpy}")


__all__ = ["HASIMOTO", "periodic_oseen", "rpy_correction", "stokeslet_report", "hydrodynamic_radius", "fmt_report",
           "StokesletReport"]
