"""Single-mode relaxation: the IBM's decay rate of a shape mode against linear Stokes theory (resolution test).

A sphere of radius R = 1 is perturbed by one real spherical harmonic, r = R (1 + eps Y_l0), with no
background flow. The IBM velocity of this shape, projected on the mode, gives the relaxation rate
omega_l = -<u_n, Y_l0> / (eps R <Y_l0, Y_l0>) (quadrature with the dual-cell areas), in 1/tau,
tau = mu R^3 / kappa: the time unit of the perturbation analysis, so the two time axes are compared
directly. Two membranes, equal viscosities inside and outside:

* ``"clean"``: bending force only, no tension, no area constraint -- a clean interface (Lamb's drop modes).
  A normal force density f_n Y_lm on a sphere moves it radially at u_r = m_l f_n R / mu with
  m_l = 2 l (l+1) / ((2l-1)(2l+1)(2l+3)) (at l = 2 with an interfacial tension gamma this is Taylor's rate
  40 (lam+1) / ((2 lam+3)(19 lam+16)) gamma / (mu R) at lam = 1). The Helfrich force of the mode is
  f_n = -kappa (l-1) l (l+1) (l+2) eps / R^3, so omega_l = m_l (l-1) l (l+1) (l+2); an imposed uniform tension
  sigma_0 adds m_l (l-1)(l+2) sigma_0.
* ``"inextensible"``: the local area constraint of :mod:`vesicle_core.solver.tension` (a quasi-spherical vesicle):
  omega_l = Gamma_l + A_l sigma_0 of eq. (11), the perturbation analysis' own rates.

:func:`resolution_table` reports l_res: the highest l whose rate ratio IBM / theory stays within a
tolerance (5%) of 1 for every l up to it, on a given grid. l_* grows like S^0.4, so this says which N a
given flow strength needs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import ConfigError, check_range
from ..geometry.surface import dot_rows
from ..model.resolution import DEFAULT_KERNEL


def clean_mobility(l):
    """Normal mobility of a clean, equal-viscosity spherical interface for mode l [R / mu]."""
    l = np.asarray(l, dtype=float)
    return 2.0 * l * (l + 1.0) / ((2.0 * l - 1.0) * (2.0 * l + 1.0) * (2.0 * l + 3.0))


def theory_rate(l, membrane="clean", sigma0=0.0):
    """Linear relaxation rate of mode l in 1/tau (see the module docstring)."""
    from ..model.modes import a_l, gamma_l

    l = np.asarray(l, dtype=float)
    if membrane == "clean":
        return clean_mobility(l) * ((l - 1) * l * (l + 1) * (l + 2) + (l - 1) * (l + 2) * sigma0)
    if membrane == "inextensible":
        return gamma_l(l) + a_l(l) * sigma0
    raise ConfigError(f"membrane must be 'clean' or 'inextensible', got {membrane!r}")


def _y_l0(l, cos_theta):
    """Real, orthonormal Y_l0 = sqrt((2l+1)/(4 pi)) P_l(cos theta)."""
    from scipy.special import eval_legendre

    return math.sqrt((2 * l + 1) / (4 * math.pi)) * eval_legendre(l, cos_theta)


@dataclass(frozen=True)
class RateResult:
    l: int
    rate: float  # IBM, 1/tau
    theory: float  # 1/tau

    @property
    def ratio(self) -> float:
        return self.rate / self.theory


def mode_rate(l, N, n_vertices, *, L=5.0, membrane="clean", sigma0=0.0, eps=1e-3, family="quasiuniform",
              seed=0, backend="numpy", Lambda=1e5, kernel=DEFAULT_KERNEL, coupling="kernel",
              sharp_floor=None, cg_tol=1e-9, tension_space="triangle", tension_l_max=None) -> RateResult:
    """IBM relaxation rate of r = 1 + eps Y_l0 on an N^3 grid of edge L (one Stokes solve, or a tension solve).

    The mesh axis is tilted away from the grid axes (a fixed rotation), so the mode does not line up with
    the grid. ``sigma0``: a uniform tension added as the force sigma0 H (both membranes). ``coupling`` and
    ``sharp_floor``: the run parameters of those names (None: the parameter's default). ``cg_tol``: the tension
    solve's tolerance (inextensible; rms area strain of the residual, against ~3e-3 at the start for eps = 1e-3).
    ``tension_space``, ``tension_l_max``: the inextensible membrane's tension, one per triangle or the harmonic one
    (:mod:`vesicle_core.solver.tension_harmonic`; the run parameters of those names).
    """
    from ..model.run_config import RunConfig
    from ..solver import membrane as B
    from ..solver.mobility import IBMSolver

    check_range("l", l, 2, 200, integer=True)
    v, f = _sphere(family, n_vertices, seed)
    rot = _rotation()
    n = v @ rot.T  # mesh directions in the grid frame
    cos_t = v[:, 2]  # the mode's axis is the mesh's z axis
    X = n * (1.0 + eps * _y_l0(l, cos_t))[:, None]
    extra = {} if sharp_floor is None else {"sharp_floor": sharp_floor}
    cfg = RunConfig(chi=0.0, stretch=0.0, N=N, L=L, Lambda=0.0, K_volume=0.0, scheme="projection", backend=backend,
                    kernel=kernel, coupling=coupling, **extra)
    solver = IBMSolver(f, X, cfg)
    xp = solver.xp
    Xd = xp.asarray(X)
    F, geo = solver.forces(Xd)
    if sigma0:
        F = F + sigma0 * geo.H
    if membrane == "clean":
        U = solver.induced_displacement(Xd, F, 1.0, advance=False)
    elif membrane == "inextensible":
        from ..solver.mobility import IBMMobility
        from ..solver.tension import TensionSolver

        mob = IBMMobility(solver.coupler, solver.stokes)
        mob.prepare(Xd)
        zero = xp.zeros(geo.area.shape[0])
        if tension_space == "harmonic":
            from ..solver.tension_harmonic import HarmonicSpace, HarmonicTensionSolver

            sp = HarmonicSpace(X, f, solver.be.asnumpy(geo.area).copy(), tension_l_max)
            ts = HarmonicTensionSolver(mob, solver.membrane.topo, sp, Lambda, tol=cg_tol, maxiter=2000)
            _, _, U = ts.solve(geo, F, 0.0, zero, 1.0, np.zeros(sp.K))  # dt = 1: the constrained velocity
        elif tension_space == "triangle":
            ts = TensionSolver(mob, solver.membrane.topo, geo.area.copy(), Lambda, tol=cg_tol, maxiter=2000)
            _, U = ts.solve(geo, F, 0.0, zero, 1.0, zero)  # dt = 1: the velocity of the constrained membrane
        else:
            raise ConfigError(f"tension_space must be 'triangle' or 'harmonic', got {tension_space!r}")
    else:
        raise ConfigError(f"membrane must be 'clean' or 'inextensible', got {membrane!r}")
    U = solver.be.asnumpy(U)
    from ..solver.tension import dual_areas

    w = solver.be.asnumpy(dual_areas(B.geometry(Xd, solver.membrane.topo), solver.membrane.topo))
    un = dot_rows(U, n)
    Y = _y_l0(l, cos_t)
    amp = float(np.sum(w * un * Y) / np.sum(w * Y * Y))
    return RateResult(int(l), -amp / eps, float(theory_rate(l, membrane, sigma0)))


@lru_cache(maxsize=8)
def _sphere(family, n_vertices, seed):
    """Unit-sphere mesh, cached: a resolution table reuses one mesh for every l (quasi-uniform meshes of
    10^4 vertices take seconds to build)."""
    from ..geometry.mesh import unit_sphere

    v, f = unit_sphere(family, n_vertices=n_vertices, seed=seed)
    v.setflags(write=False)
    f.setflags(write=False)
    return v, f


def _rotation():
    a, b = 0.37, 0.61  # fixed tilt (radians) about x then z
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    rz = np.array([[math.cos(b), -math.sin(b), 0], [math.sin(b), math.cos(b), 0], [0, 0, 1]])
    return rz @ rx


def l_res(ratios: dict, tol=0.05) -> int:
    """Highest l such that every measured l' <= l has |ratio - 1| <= tol (0 if the first fails)."""
    best = 0
    for l in sorted(ratios):
        if abs(ratios[l] - 1.0) > tol:
            break
        best = l
    return best


def box_factor_l2(N, n_vertices, L=5.0, **kw) -> float:
    """r(L) / r(inf) of mode l = 2, from boxes L and ~7 R at the same h (r = r_inf - c / L^3): the periodic images slow
    l = 2 by ~5% at L = 5 R, and modes l >= 3 move by < 0.1% (docs/explanation/resolution.md, "Kernels and
    resolution")."""
    h = L / N
    N7 = 2 * round(7.0 / h / 2)
    L7 = N7 * h
    r5 = mode_rate(2, N, n_vertices, L=L, **kw).ratio
    r7 = mode_rate(2, N7, n_vertices, L=L7, **kw).ratio
    c = (r7 - r5) / (1 / L**3 - 1 / L7**3)
    return r5 / (r7 + c / L7**3)


def resolution_table(Ns, ls, n_vertices_of=None, membrane="clean", L=5.0, tol=0.05, box_factor=None,
                     kernel=DEFAULT_KERNEL, coupling="kernel", sharp_floor=None, edge=2.0, box_correct=False,
                     lh_max=2.0, progress=None, cg_tol=1e-9, tension_space="triangle", eps=1e-3):
    """Rate ratios IBM/theory per (N, l) and l_res per N, for one kernel and coupling.

    ``n_vertices_of(N)``: the mesh for each grid (default: mean edge ``edge`` h; 2h is the project's rule for the
    kernel coupling, h the sharp coupling's). ``box_factor[l]`` divides out the periodic-box effect; or
    ``box_correct=True`` measures it for l = 2 (:func:`box_factor_l2`, two more solves per grid). Modes with
    l h > ``lh_max`` are skipped (far past any kernel's resolution). ``progress``: called with a line per grid.
    ``cg_tol``, ``tension_space``: the tension solve's tolerance and space (inextensible membrane). ``eps``: the
    mode's amplitude; the constrained rates of l >~ 15 need 1e-4 to be linear (eps l^2 is the curvature's relative
    perturbation: at 1e-3 the l = 20 rate comes out 9% slow, docs/history/solver.md).
    """
    kw = {"kernel": kernel, "coupling": coupling, "sharp_floor": sharp_floor, "cg_tol": cg_tol,
          "tension_space": tension_space, "eps": eps}
    out = {}
    for N in Ns:
        nv = n_vertices_of(N) if n_vertices_of else default_vertices(N, L, edge)
        bf = dict(box_factor or {})
        if box_correct and 2 in ls:
            bf[2] = box_factor_l2(N, nv, L, **kw)
        ratios = {}
        for l in ls:
            if l * L / N > lh_max:
                break
            r = mode_rate(l, N, nv, L=L, membrane=membrane, **kw).ratio
            ratios[l] = r / bf.get(l, 1.0)
        out[N] = {"n_vertices": nv, "ratios": ratios, "l_res": l_res(ratios, tol), "box_factor": bf}
        if progress:
            progress(f"N = {N}, {nv} vertices: l_res = {out[N]['l_res']}, "
                     + " ".join(f"{l}:{r:.3f}" for l, r in ratios.items()))
    return out


def fit_damping(tables: dict, L=5.0, below=0.99) -> tuple[float, float]:
    """Fit ratio = exp(-(l h / a)^p) to the ratios below ``below`` of :func:`resolution_table` results
    ({N: {"ratios": {l: r}}}), least squares in log(-log r) against log(l h). Returns (a, p)."""
    x, y = [], []
    for N, row in tables.items():
        for l, r in row["ratios"].items():
            if 0.0 < r < below:
                x.append(math.log(l * L / N))
                y.append(math.log(-math.log(r)))
    if len(x) < 2:
        raise ConfigError("fit_damping needs at least two ratios below the threshold")
    p, c = np.polyfit(x, y, 1)  # log(-log r) = p log(l h) - p log a
    return float(math.exp(-c / p)), float(p)


def default_vertices(N, L=5.0, edge=2.0):
    """Vertex count whose mean edge is ~``edge`` h (h = L/N; the project's rule is 2h, the sharp coupling's h) on the
    unit sphere: ~ 4 pi / (0.433 (edge h)^2 x 2)."""
    from ..geometry.mesh import vertices_for_edge

    return vertices_for_edge(edge * L / N)
