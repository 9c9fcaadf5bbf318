"""The coupled IBM operator: the run's :class:`IBMSolver` and its steady part as a mobility ``velocity = M(X) F``.

:class:`IBMSolver` lives here, next to :class:`IBMMobility`, because both are the same spread-Stokes-interpolate path
on one Grid, Backend and Coupler; the solver adds the membrane forces and the fluid state of finite Re.

:class:`IBMSolver` (one per run) builds the array module, grid, Stokes solver, coupler and membrane of a
:class:`~vesicle_core.model.run_config.RunConfig` and gives the integrators the forces F(X) (A7) and the induced
displacement J Gamma of eq. (29): spread (28), the exponential update (23) of the periodic Stokes flow (its steady
limit at Re = 0), interpolate (16). :class:`IBMMobility` is the mobility (Lagrangian forces in, vertex velocities
out):

    M(X) = J(X) L^{-1} xi S(X)        interpolate (16) . periodic steady Stokes (21-23) . spread (28)

M is symmetric positive semi-definite in the Lagrangian inner product, because spreading and interpolation
share one stencil (S = J^T / h^3) and the Stokes operator xi / lam_k is symmetric positive semi-definite.
The inextensible integrator of :mod:`vesicle_core.solver.integrators` and the tension solve of
:mod:`vesicle_core.solver.tension`
use only :meth:`IBMMobility.prepare` and :meth:`IBMMobility.apply`, so another mobility (a boundary
integral, a wall-bounded solver) can be swapped in without touching them; the fixed-step integrators use
:meth:`IBMSolver.induced_displacement`, the time-integrated displacement of eq. (29) at finite Re.

:func:`pair_table` measures the IBM's own pair mobility M(r) = f(r) I + g(r) r_hat r_hat, averaged over
positions relative to the grid, and :func:`local_mobility_matrix` assembles the near-field part of M
(pairs closer than a cut-off) as a sparse matrix: that is the local preconditioner of the tension solve
(Kallemov, Bhalla, Griffith & Donev, CAMCoS 11 (2016): IB constraints preconditioned by a local mobility).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from . import membrane as B

if TYPE_CHECKING:
    from ..model.run_config import RunConfig


class IBMMobility:
    """M(X) = J L^{-1} xi S on one Grid, Backend and Coupler (steady Stokes, no background flow)."""

    def __init__(self, coupler, stokes, grid_buffer=None):
        self.coupler = coupler
        self.stokes = stokes
        self.grid = coupler.grid
        self.backend = coupler.backend
        self._buf = grid_buffer if grid_buffer is not None else self.backend.empty(self.grid.field_shape)
        self.n_products = 0  # Stokes solves done through this object (cost accounting)
        # their wall time: spreading, the FFT solve and interpolation (on a GPU the launches are asynchronous, so it
        # counts what the host waited for, a lower bound)
        self.seconds = 0.0

    def prepare(self, X):
        """Stencils for the points X (M, 3); every apply() until the next prepare() uses them."""
        self.coupler.prepare(X)

    def apply(self, F, scale=1.0):
        """scale * M F for Lagrangian forces F (M, 3) at the prepared points -> velocities (M, 3)."""
        t0 = time.perf_counter()
        f = self.coupler.spread(F)
        if scale == 1.0:
            u = self.stokes.velocity(f, out=self._buf)
        else:  # the scale is folded into the Stokes symbols (no extra pass over the grid)
            u = self.stokes.step(f, scale, out=self._buf)
        self.n_products += 1
        out = self.coupler.interpolate(u)
        self.seconds += time.perf_counter() - t0
        return out


def coupling_filter(cfg: RunConfig):
    """The Stokes solver's force filter for ``cfg.coupling``: None (kernel) or the sharpening symbol (sharp)."""
    if cfg.coupling == "kernel":
        return None
    from .kernels import sharpening_symbol

    return sharpening_symbol(cfg.N, cfg.kernel, cfg.sharp_floor)


class IBMSolver:
    """Membrane forces + spreading + periodic Stokes + interpolation on one array module.

    ``faces``, ``X0``: the mesh (its shape X0 is the reference of the area penalty and the volume); the inextensible
    scheme carries the tension as an unknown, so its membrane has no penalty (A5).
    """

    def __init__(self, faces, X0, cfg: RunConfig):
        from .backend import get_backend
        from .ibm import Coupler, Grid
        from .stokes import StokesSolver

        self.cfg = cfg
        self.be = get_backend(cfg.backend, cfg.dtype, fft_workers=cfg.fft_workers)
        xp = self.be.xp
        self.xp = xp
        self.grid = Grid(cfg.N, cfg.L)
        self.stokes = StokesSolver(self.grid, self.be, rho_bar=cfg.rho_bar, force_filter=coupling_filter(cfg))
        # reused stencil and grid buffers (no page faults per step)
        self.coupler = Coupler(self.grid, self.be, kernel=cfg.kernel)
        self._grid_buf = self.be.empty(self.grid.field_shape)
        # the inextensible scheme carries the tension as an unknown: no penalty (A5) in the force
        penalty = 0.0 if cfg.scheme == "inextensible" else cfg.Lambda_eff
        self.membrane = B.Membrane.from_mesh(
            xp.asarray(X0, dtype=xp.float64), faces, xp=xp, Lambda=penalty, K_volume=cfg.K_volume,
            K_area=cfg.K_area, area_model=cfg.area_model,
        )
        # wall time of induced_displacement (stencil, spreading, Stokes, interpolation), as IBMMobility.seconds
        self.seconds = 0.0

    def forces(self, X):
        return self.membrane.forces(X)

    def induced_displacement(self, X, F, dt, advance=True, same_points=False):
        """J Gamma: the induced displacement of the vertices over dt (steady Stokes: J u_ind dt).

        ``advance``: at finite Re, step the stored fluid state (False: steady response, state untouched).
        ``same_points``: X is the same as in the previous call, so its stencil is reused.
        """
        t0 = time.perf_counter()
        if not same_points:
            self.coupler.prepare(X)
        f = self.coupler.spread(F)
        if self.cfg.rho_bar > 0 and not advance:
            G = self.stokes.velocity(f, out=self._grid_buf)
            G *= dt
        else:
            G = self.stokes.step(f, dt, out=self._grid_buf)
        out = self.coupler.interpolate(G)
        self.seconds += time.perf_counter() - t0
        return out

    def membrane_velocity(self, X):
        """Induced velocity of the membrane, steady Stokes, no background flow (for dt estimates)."""
        F, _ = self.forces(X)
        return self.induced_displacement(X, F, 1.0, advance=False)


@dataclass(frozen=True)
class PairTable:
    """IBM pair mobility on a radial grid r (in units of h): M(r) = f(r) I + g(r) r_hat r_hat [1/mu]."""

    r: np.ndarray  # (n,) distances / h, r[0] = 0
    f: np.ndarray  # (n,) transverse part
    g: np.ndarray  # (n,) longitudinal minus transverse part
    h: float

    @property
    def self_mobility(self) -> float:
        return float(self.f[0])

    @property
    def hydrodynamic_radius(self) -> float:
        """a_h / h from the self-mobility 1 / (6 pi mu a_h) (periodic box: slightly below free space)."""
        return 1.0 / (6.0 * np.pi * self.f[0] * self.h)

    def __call__(self, dist):
        """(f, g) at distances ``dist`` (in R), linear interpolation, 0 beyond the table."""
        s = np.asarray(dist) / self.h
        f = np.interp(s, self.r, self.f, right=0.0)
        g = np.interp(s, self.r, self.g, right=0.0)
        return f, g


def pair_table(mobility: IBMMobility, r_max=4.0, n_r=33, n_positions=4, seed=0) -> PairTable:
    """Measure the IBM's pair mobility by spreading a unit force and interpolating the velocity around it.

    One point force along x at ``n_positions`` random sub-grid offsets (one Stokes solve each); the
    velocity is sampled on 13 directions per distance, so the table averages the small dependence of the
    regularised Stokeslet on the position within a cell (the kernel's translation invariance error).
    Positions and sampling points are placed near the box centre; the table is in the units of M.
    """
    grid = mobility.grid
    h = grid.h
    rng = np.random.default_rng(seed)
    r = np.linspace(0.0, r_max, n_r)
    dirs = rng.standard_normal((13, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    f_acc = np.zeros(n_r)
    g_acc = np.zeros(n_r)
    xp = mobility.backend.xp
    for _ in range(n_positions):
        x0 = rng.uniform(0.0, h, 3)
        pts = (x0[None, None, :] + h * r[:, None, None] * dirs[None, :, :]).reshape(-1, 3)
        X = np.vstack([x0[None, :], pts])
        F = np.zeros_like(X)
        F[0, 0] = 1.0
        mobility.prepare(xp.asarray(X))
        U = mobility.backend.asnumpy(mobility.apply(xp.asarray(F)))[1:].reshape(n_r, len(dirs), 3)
        # U = f e_x + g (d . e_x) d: project on e_x and on the part of d normal to e_x
        c = dirs[:, 0]  # d . e_x
        ux = U[..., 0]
        ud = np.einsum("rdk,dk->rd", U, dirs)
        # ux = f + g c^2, ud = (f + g) c  -> least squares over directions
        A = np.stack([np.ones_like(c), c**2], 1)
        Ab = np.stack([c, c], 1)
        for i in range(n_r):
            lhs = np.vstack([A, Ab])
            rhs = np.concatenate([ux[i], ud[i]])
            (fi, gi), *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
            f_acc[i] += fi
            g_acc[i] += gi
    f_acc /= n_positions
    g_acc /= n_positions
    g_acc[0] = 0.0  # no direction at r = 0
    return PairTable(r, f_acc, g_acc, h)


def local_mobility_matrix(X, table: PairTable, r_cut=None, taper=True):
    """Sparse (3V, 3V) near-field mobility: self terms f(0) I and pairs closer than r_cut (in R).

    ``taper`` multiplies the pair blocks by (1 - (r/r_cut)^2)^2 so the truncated matrix stays positive
    definite (a hard cut of a positive kernel need not be). Returns a scipy.sparse CSR matrix (float64).
    """
    import scipy.sparse as sp
    from scipy.spatial import cKDTree

    X = np.asarray(X, dtype=np.float64)
    V = X.shape[0]
    r_cut = float(table.r[-1] * table.h if r_cut is None else r_cut)
    pairs = cKDTree(X).query_pairs(r_cut, output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    d = X[j] - X[i]
    dist = np.linalg.norm(d, axis=1)
    rhat = d / dist[:, None]
    f, g = table(dist)
    if taper:
        w = (1.0 - (dist / r_cut) ** 2) ** 2
        f, g = f * w, g * w
    blocks = f[:, None, None] * np.eye(3)[None] + g[:, None, None] * rhat[:, :, None] * rhat[:, None, :]
    rows = (3 * i[:, None, None] + np.arange(3)[None, :, None]).repeat(3, 2)
    cols = (3 * j[:, None, None] + np.arange(3)[None, None, :]).repeat(3, 1)
    off = sp.coo_matrix((blocks.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * V, 3 * V))
    diag = sp.identity(3 * V, format="csr") * table.self_mobility
    return (diag + off + off.T).tocsr()
