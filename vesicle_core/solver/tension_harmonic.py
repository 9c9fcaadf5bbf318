"""A Galerkin tension in real spherical harmonics: the inextensible scheme's ``tension_space: harmonic``.

The triangle tension (:mod:`vesicle_core.solver.tension`) carries one unknown per triangle. That space has near-null
modes, triangle patterns that exert almost no force (docs/history/solver.md, "Tension noise"), which hold most of its
variance (a checkerboard) and slow its CG. Here the tension is a smooth field instead,

    sigma(x) = sum_k c_k Y_k(theta(x), phi(x)),    k = (l, m), 0 <= l <= l_t, real Y_lm,

evaluated at each triangle's centroid in material coordinates (the direction of the reference mesh's vertices
from its volume centroid; the mesh is a sphere mesh mapped onto the ellipsoid, so these are its own sphere
coordinates up to a smooth map). B (F, K) holds the Y_k at the centroids, so the per-triangle tension is B c and
its force -D^T B c. What is constrained is the projection of the local area change on the space (Galerkin):

    (dt B^T D M D^T B + G / Lambda) c = B^T [dt D (M F + u_inf) + (A - A^0)],     G = B^T W B,

symmetric positive definite (G is the mass matrix of the space in the reference areas W). Triangle-scale area
changes outside the space are not held: the vertices can slide tangentially on the mesh scale.

Fixed-tension ensemble (run parameter ``tension_fixed``, ``hold_area=False``): the l = 0 coefficient is not an
unknown but the prescribed uniform tension, so the total area is free while the l >= 1 projection of the local area
change is still held. The CG then runs on the l >= 1 coefficients (the operator and the preconditioner restricted by
the mask). At a fixed area the uniform tension is a Lagrange multiplier, and its mean over a noisy run is not the
tension the shape modes feel (docs/history/thermal.md, section 7); at a fixed tension the equilibrium spectrum has
a known
tension to be compared with.

Preconditioner ("diagonal in l", the quasi-spherical vesicle's own operator): on a sphere the area rate per unit
tension of a mode Y_lm depends on l only (rotational invariance), rho_l. Here rho_l is measured on the IBM itself,
on the current shape (Rayleigh quotients v.Av / v.Gv of random v: one Stokes solve for each l <= EXACT_L, one shared
by the higher l, read off block by block; see ``measure_rho``), so it carries the grid's damping of mode l and the
shape's l = 0 response (zero on a sphere: a uniform tension moves nothing there) without a model.
P = S^(1/2) G S^(1/2), S = diag(dt rho_l + 1/Lambda), applied with the Cholesky factor of G. rho_l is re-measured
every ``refresh`` solves, and early when a warm solve needed ``stale`` or more iterations (the shape has moved away
from the one measured). Measured (docs/history/solver.md, "Fewer solves per step"): 4 solves a measurement instead of
l_t + 1, 547 Stokes solves in the S = 2224 run at 128^3 against 635, 649 against 856 at 256^3.
Prior art: ves3d's ``DiagonalSpectral`` tension preconditioner (Malhotra, Rahimian, Zorin & Biros), a diagonal
in spherical harmonics.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from ..xp import to_numpy
from .tension import SolveInfo, face_D, face_DT, pcg

#: a warm solve needing this many CG iterations re-measures rho_l at the next one (warm steps need 1, max 3-5)
STALE_ITERATIONS = 4
#: solves after which rho_l is re-measured in any case
RHO_REFRESH = 50
#: fewest solves between two re-measurements that iteration counts asked for
STALE_GAP = 10
#: rho_l of l <= EXACT_L is measured one l per Stokes solve, the higher l together in RHO_PROBES solves
EXACT_L = 2
RHO_PROBES = 1


def real_ylm(l_max, theta, phi):
    """Real orthonormal spherical harmonics at the points, (n, (l_max+1)^2), and the l of each column.

    Columns per l: m = 0, then (sqrt 2 Re Y_lm, sqrt 2 Im Y_lm) for m = 1..l (harmonics' normalisation)."""
    from ..geometry.ylm import _legendre_rows

    th = np.asarray(theta, float).ravel()
    ph = np.asarray(phi, float).ravel()
    cols = {}
    for m, P in _legendre_rows(np.cos(th), np.sin(th), l_max):
        for l in range(m, l_max + 1):
            if m == 0:
                cols[(l, 0)] = P[l - m]
            else:
                cols[(l, m)] = math.sqrt(2.0) * P[l - m] * np.cos(m * ph)
                cols[(l, -m)] = math.sqrt(2.0) * P[l - m] * np.sin(m * ph)
    keys = [(l, m) for l in range(l_max + 1) for m in [0] + [s * k for k in range(1, l + 1) for s in (1, -1)]]
    Y = np.stack([cols[k] for k in keys], axis=1)
    return Y, np.array([k[0] for k in keys])


def default_l_max(X0, faces) -> int:
    """Half the mesh's resolvable l (surface.resolvable_l_max: pi R / mean edge), the resolved_field default:
    four edges per wavelength. 642 vertices: 10; 2562: 20; 10242: 40."""
    from ..geometry.surface import resolvable_l_max

    return max(2, resolvable_l_max(X0, faces) // 2)


class HarmonicSpace:
    """The tension space: B (F, K), the l of each column, the mass G = B^T W B and its Cholesky factor."""

    def __init__(self, X0, faces, A0, l_max=None, check=True):
        from ..geometry.surface import volume_centroid
        from ..geometry.ylm import _angles

        X0 = np.asarray(X0, dtype=float)
        faces = np.asarray(faces)
        self.l_max = default_l_max(X0, faces) if l_max is None else int(l_max)
        if self.l_max < 0:
            raise ConfigError(f"tension_l_max must be >= 0, got {self.l_max}")
        from ..geometry.surface import resolvable_l_max

        l_res = resolvable_l_max(X0, faces)
        if check and self.l_max > l_res:
            raise ConfigError(f"tension_l_max = {self.l_max} exceeds the mesh's resolvable l {l_res} (pi R / mean "
                              f"edge): the inf-sup constant collapses there (0.48 against 1.95 at 162 vertices, "
                              f"docs/history/solver.md)")
        c0 = volume_centroid(X0, faces)
        u = X0 - c0
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        cen = u[faces].mean(axis=1)
        _, theta, phi = _angles(cen)
        self.B, self.l = real_ylm(self.l_max, theta, phi)
        self.K = self.B.shape[1]
        if self.K > faces.shape[0]:
            raise ConfigError(f"tension_l_max = {self.l_max} gives {self.K} harmonics, more than the mesh's "
                              f"{faces.shape[0]} triangles")
        self.W = np.asarray(A0, dtype=float)
        self.G = self.B.T @ (self.W[:, None] * self.B)
        # Fortran order: LAPACK's potrs reads the factor in place, where a C-ordered one was copied (and checked for
        # NaN) on every solve, 22 MB at l_t = 40: 46 ms a solve against 8 ms, with the same bits (G_solve)
        self.G_chol = np.asfortranarray(np.linalg.cholesky(self.G))

    def faces(self, c):
        """Per-triangle tension B c."""
        return self.B @ c

    def test(self, f):
        """B^T f: the projection of a per-triangle quantity on the space (Galerkin test)."""
        return self.B.T @ f

    def G_solve(self, r):
        """G^-1 r by the Cholesky factor (the factor is finite by construction; r is checked, as before)."""
        import scipy.linalg as sl

        return sl.cho_solve((self.G_chol, True), np.asarray_chkfinite(r), check_finite=False)

    def fit(self, sigma_faces):
        """Coefficients of the W-orthogonal projection of a per-triangle field on the space."""
        return self.G_solve(self.B.T @ (self.W * np.asarray(sigma_faces, float)))

    def project_faces(self, f_faces):
        """The W-orthogonal projection of a per-triangle field on the space, per triangle."""
        return self.B @ self.fit(f_faces)


class HarmonicTensionSolver:
    """PCG in the coefficients c (see the module docstring). Same interface as tension.TensionSolver: ``solve``
    returns the per-triangle tension B c and the velocity; ``last`` is a SolveInfo."""

    def __init__(self, mobility, topo, space: HarmonicSpace, Lambda, tol=1e-5, maxiter=200, refresh=RHO_REFRESH,
                 stale=STALE_ITERATIONS, probes=RHO_PROBES, seed=0, hold_area=True, secant=False, basis_dtype=None):
        if not Lambda > 0:
            raise ConfigError(f"Lambda (area-stretch modulus) must be > 0 for the tension solve, got {Lambda!r}")
        self.mobility = mobility
        self.topo = topo
        self.space = space
        self.Lambda = float(Lambda)
        self.tol = float(tol)
        self.maxiter = int(maxiter)
        self.refresh = int(refresh)
        self.stale = int(stale)
        self.probes = int(probes)
        exact = min(space.l_max, EXACT_L)
        self.rho_solves = exact + 1 + (self.probes if space.l_max > exact else 0)  # Stokes solves per measurement
        self.rng = np.random.default_rng(seed)
        self.area = float(space.W.sum())
        self.rho = None  # measured area rate per unit tension per l (rho_l), at the last refresh
        self._uses = 0
        self.extra_solves = 0  # Stokes solves spent measuring rho_l
        self.refreshes = 0
        self.last = SolveInfo(0, 0.0, 0.0)
        # hold_area False (run parameter tension_fixed): the l = 0 coefficient is not solved for but kept at the
        # value the caller passes in c0, so the total area is free and the uniform tension is prescribed
        self.hold_area = bool(hold_area)
        self.free = np.ones(space.K, dtype=bool) if self.hold_area else space.l > 0
        from .tension_secant import SecantPreconditioner  # the diagonal in l starts a BFGS model fed by every product

        self.secant = SecantPreconditioner(space.G, self.Lambda, self.free) if secant else None
        self.noise_c = None  # the last solve's modelled noise response (solve's ``unpredicted``)
        # B on the mesh's device (NumPy: B itself). On a GPU the products B c and B^T f of every CG iteration then run
        # there, and only the K coefficients cross, not the F per-triangle values (with F K host flops each way:
        # 138 M at 82k triangles and l_t = 40). ``basis_dtype`` float32 (the run's float32 grid): these products read
        # half the memory, and B is the step's largest array (F K: 243 MB at 9512 vertices, 1.2 GB at 21398), so
        # they take about half as long; their rounding (~1e-6 of sigma) is that of the float32 grid the mobility
        # already works on (tests/solver/test_step_cost.py). Coefficients, G and every other use of B stay float64.
        self._B = topo.xp.asarray(space.B if basis_dtype is None else space.B.astype(basis_dtype))

    # ------------------------------------------------------------------ operator and preconditioner
    def _xp_faces(self, c):
        """Per-triangle tension B c on the mesh's device, from host coefficients c."""
        xp = self.topo.xp
        return (self._B @ xp.asarray(c, dtype=self._B.dtype)).astype(xp.float64, copy=False)

    def _test(self, f):
        """B^T f (host, K) of a per-triangle field f on the mesh's device: the space's Galerkin test."""
        return np.asarray(to_numpy(self._B.T @ f.astype(self._B.dtype, copy=False)), dtype=np.float64)

    def apply_rate(self, c, geo):
        """(B^T D M D^T B c, M D^T B c): the area rate per unit time of a tension c and its velocity."""
        q = self.mobility.apply(face_DT(self._xp_faces(c), geo, self.topo))
        rate = self._test(face_D(q, geo, self.topo))
        if self.secant is not None:
            self.secant.record(c, rate)
        return rate, q

    def operator(self, c, geo, dt):
        """(A c, M D^T B c) with A = dt B^T D M D^T B + G / Lambda."""
        rate, q = self.apply_rate(c, geo)
        return dt * rate + self.space.G @ c / self.Lambda, q

    def measure_rho(self, geo, seed=None):
        """rho_l = v.(B^T D M D^T B) v / v.G v for a random v in the span of each l's harmonics; ``seed``: the draw
        (the step number in runs, so that a resumed run measures what the first call did).

        l <= EXACT_L one Stokes solve each; the higher l share ``probes`` solves: v is random over all of them and
        rho_l is read off the block of l, v_l.(A v) / v_l.(G v). The cross terms v_l.A v_l' (l' != l) vanish on a
        sphere, where A is diagonal in l, and average out over the 2 l + 1 coefficients of a block elsewhere; the
        low l, whose rates are the smallest (rho_0 ~ 0.01 of the others) and the shape couples most, are measured
        alone."""
        sp = self.space
        rng = self.rng if seed is None else np.random.default_rng(seed)
        rho = np.empty(sp.l_max + 1)
        exact = min(sp.l_max, EXACT_L)
        for l in range(exact + 1):
            v = np.where(sp.l == l, rng.standard_normal(sp.K), 0.0)
            rate, _ = self.apply_rate(v, geo)
            rho[l] = float(v @ rate) / float(v @ (sp.G @ v))
        if sp.l_max > exact:
            num = np.zeros(sp.l_max + 1)
            den = np.zeros(sp.l_max + 1)
            high = sp.l > exact
            for _ in range(self.probes):
                v = np.where(high, rng.standard_normal(sp.K), 0.0)
                rate, _ = self.apply_rate(v, geo)
                np.add.at(num, sp.l, v * rate)
                np.add.at(den, sp.l, v * (sp.G @ v))
            rho[exact + 1:] = num[exact + 1:] / den[exact + 1:]
        self.extra_solves += self.rho_solves
        self.refreshes += 1
        # a mode no flow can change (rho <= 0 only by round-off; the sphere's l = 0) is held by the compliance
        self.rho = np.maximum(rho, 0.0)
        self._uses = 0
        if self.secant is not None and not self.secant.ready:
            self.secant.start(self.rho, sp.l)

    def precondition(self, r, dt):
        if self.secant is not None and self.secant.ready:
            return self.secant(r, dt)
        s = 1.0 / np.sqrt(dt * self.rho[self.space.l] + 1.0 / self.Lambda)
        return s * self.space.G_solve(s * r)

    def strain_rms(self, r):
        """rms strain of the residual's field in the space: sqrt(r.G^-1 r / A)."""
        return math.sqrt(max(float(r @ self.space.G_solve(r)), 0.0) / self.area)

    # ------------------------------------------------------------------ the solve
    def solve(self, geo, F, u_inf, area_error, dt, c0, seed=None, warm=True, unpredicted=None, noise_c=None):
        """Coefficients c, per-triangle tension B c and velocity U (V, 3) of one step; the mobility must be prepared
        at geo's positions. Raises NumericalInstability when PCG does not converge. ``warm``: c0 is a prediction of
        the answer (a step's solve), so that many iterations mean a stale rho_l; the thermal drift's solves from
        c0 = 0 pass False. ``unpredicted``: the part of u_inf that c0 does not foresee (a thermal step's noise); with
        the secant model, c0 (the last step's tension) loses that step's noise response ``noise_c`` and gains the
        model's response to this step's noise and area error, free of Stokes solves (kept in ``self.noise_c``)."""
        sp = self.space
        secant = self.secant is not None and self.secant.ready
        if self.rho is None or (self._uses >= self.refresh and not secant):  # the model tracks the shape itself
            self.measure_rho(geo, seed)
        self._uses += 1
        c = np.array(c0, dtype=float, copy=True)
        self.noise_c = None
        if unpredicted is not None and secant:
            c -= 0.0 if noise_c is None else np.asarray(noise_c, dtype=float)
            self.noise_c = self.secant(self._test(dt * face_D(unpredicted, geo, self.topo) + area_error), dt)
            c += self.noise_c
        U = self.mobility.apply(F - face_DT(self._xp_faces(c), geo, self.topo)) + u_inf
        r = self._test(dt * face_D(U, geo, self.topo) + area_error) - sp.G @ c / self.Lambda
        operator, precondition = (lambda p: self.operator(p, geo, dt)), (lambda r: self.precondition(r, dt))
        if not self.hold_area:  # CG in the span of the l >= 1 coefficients: P A P and P S G^-1 S P, P the mask
            fixed = ~self.free
            r[fixed] = 0.0

            def operator(p, _op=operator):
                Ap, q = _op(p)
                Ap[fixed] = 0.0
                return Ap, q

            def precondition(r, _pre=precondition):
                z = _pre(r)
                z[fixed] = 0.0
                return z

        c, U, it, res, res0 = pcg(c, U, r, operator, precondition, lambda a, b: float(a @ b), self.strain_rms,
                                  self.tol, self.maxiter)
        self.last = SolveInfo(it, res, res0)
        if self.secant is not None:
            self.secant.update()
        if warm and it >= self.stale and self._uses >= STALE_GAP:
            # the preconditioner no longer fits the shape: re-measure at the next call (not again within STALE_GAP
            # solves, where a fresh measurement did not help: l_t near the resolvable l needs 4-22 iterations anyway)
            self._uses = self.refresh
        return c, self._xp_faces(c), U


# --------------------------------------------------------------------------- inf-sup
def inf_sup(X, faces, B=None, W=None):
    """Discrete inf-sup constant of a tension space: the smallest singular value of D^T B, normalised,

        beta = min_c |D^T B c|_{V^-1} / |B c|_W,

    with D the triangle-area gradient at X, V the barycentric vertex areas (|f|_{V^-1}^2 = sum_i |f_i|^2 / V_i: the
    L2 norm of the force density) and W the triangle areas (the L2 norm of the tension). B None: the triangle space
    (B = I). On a sphere of radius R the continuum value is min_l sqrt(l (l+1) + 4) / R = 2 / R (l = 0: a uniform
    tension pulls normally with 2 sigma / R). Dense: for checks and benchmarks (F up to a few thousand)."""
    import scipy.linalg as sl

    from . import membrane as Mb
    from .tension import dual_areas, face_D_matrix

    topo = Mb.Topology(faces, X.shape[0])
    geo = Mb.geometry(np.asarray(X, float), topo)
    D = face_D_matrix(geo, topo)  # (F, 3V), sparse
    Vm = np.repeat(dual_areas(geo, topo), 3)
    W = geo.area if W is None else np.asarray(W, float)
    DB = D.T.toarray() if B is None else np.asarray(D.T @ B)  # (3V, K)
    K = DB / np.sqrt(Vm)[:, None]
    Gm = np.diag(W) if B is None else B.T @ (W[:, None] * B)
    lam = sl.eigh(K.T @ K, Gm, eigvals_only=True, subset_by_index=[0, 0])
    return float(np.sqrt(max(lam[0], 0.0)))
