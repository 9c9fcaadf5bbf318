"""Tangential (ALE) mesh velocities for the harmonic tension (run parameter ``mesh_ale``).

The harmonic tension (:mod:`vesicle_core.solver.tension_harmonic`) holds only the projection of the local area
change on its space, so the vertices are free to slide on the mesh scale. These classes add a tangential vertex
displacement that changes the shape only at second order and keeps the mesh carrying the strain: ``AreaALE`` holds
the triangle areas, ``ShapeALE`` also their angles (docs/history/solver.md, "An ALE that keeps the triangles' shape").
"""

from __future__ import annotations

import numpy as np

from ..geometry.surface import cross_rows
from ..xp import to_numpy
from .tension_harmonic import HarmonicSpace


# --------------------------------------------------------------------------- tangential (ALE) mesh velocity
class AreaALE:
    """A tangential vertex displacement that holds the triangle areas the harmonic tension leaves free.

    The harmonic tension holds B^T (A - A^0), the projection of the area change on the space; the rest of every
    triangle's area change (the triangle scale) is not held, and the vertices then slide tangentially on the mesh
    scale. This adds to the step's displacement dX a tangential w (w . n_i = 0 at each vertex, n_i its normal)
    that makes the triangle areas after the step A^0 plus the space's part:

        min_w |W^(-1/2) (D w - y)|^2 + damp^2 |w|^2 / h^2,   y = -(I - W B G^-1 B^T)(D dX + A - A^0),

    solved exactly (:func:`damped_least_squares`: no Stokes solve). y has no component the tension holds
    (B^T y = 0), and a tangential w changes the shape only at second order, so the membrane's motion is unchanged;
    what changes is which mesh point sits where (an arbitrary Lagrangian-Eulerian mesh). ``damp`` keeps w small
    where no vertex motion reaches an area pattern (the triangle space's near-null modes: 2V unknowns against
    F = 2V - 4 rows, and ~1% of the singular values of the area rows below damp) and makes the minimiser unique, with
    a condition number sigma_max / damp ~ 400-700 (162 and 642 vertices), so w is a Lipschitz function of the step's
    data: a perturbation of X by 1e-14 moves it by ~1e-15 R. (Until 2026-12-08 the minimum was sought by 100 LSQR
    iterations, which do not converge on the near-null cluster at a few hundred vertices: that iterate moved by up
    to 5e-5 R for the same 1e-14, and the strict GPU-path tests could compare runs with an ALE only to 1e-4 R.)"""

    def __init__(self, space: HarmonicSpace, h, damp=1e-3, max_step=0.05, follow=1.0):
        self.space = space
        self.max_step = float(max_step)  # largest |w| per step, in h: the rest is left to the next steps
        self.follow = float(follow)  # ... plus this times the step's largest membrane displacement
        self.carries_area = False  # whether the triangles carry their lipid along (ShapeALE.carry)
        self.capped = 0
        self.h = float(h)
        self.damp = float(damp)
        self._order = None  # the normal equations' elimination order (elimination_order), at the first call
        self.calls = 0
        self.seconds = 0.0

    def __call__(self, X, geo, topo, dX, area_error, scale=1.0):
        """-> w (V, 3). ``scale`` in (0, 1]: the step's length over a full (bending-limited) step. The cap on |w| is
        max_step h times it plus ``follow`` times the step's largest membrane displacement |dX|, so that the mesh
        moves at a bounded speed: the area change w leaves in the held space (second order in w) then shrinks with
        dt, and the dt_strain limit, which must correct it at the next step, can act. With a cap per step, the
        elongated vesicle at 128^3 had its step driven to 8.5e-9 tau (the cap bound at every step while dt fell
        5000x)."""
        import time

        import scipy.sparse as sps

        from .tension import face_D_matrix

        t0 = time.perf_counter()
        sp = self.space
        Xn = np.asarray(to_numpy(X), float)
        faces = to_numpy(topo.faces)
        dXn = np.asarray(to_numpy(dX), float)
        err = np.asarray(to_numpy(area_error), float)
        D = face_D_matrix(geo, topo)  # (F, 3V)
        x = D @ dXn.ravel() + err
        y = -(x - sp.W * (sp.B @ sp.G_solve(sp.B.T @ x)))
        T = tangent_basis(Xn, faces)
        s = 1.0 / np.sqrt(sp.W)
        rows, rhs = [sps.diags(s) @ (D @ T) * self.h], [s * y]  # unknowns in units of h
        for r, b in self._extra_rows(Xn, dXn, T):
            rows.append(r * self.h)
            rhs.append(b)
        A = sps.vstack(rows).tocsr() if len(rows) > 1 else rows[0]
        if self._order is None:
            self._order = elimination_order(faces, Xn.shape[0])
        u = damped_least_squares(A, np.concatenate(rhs), self.damp, self._order)
        w = (T @ (u * self.h)).reshape(-1, 3)
        wmax = float(np.sqrt((w**2).sum(axis=1)).max())
        # the membrane's own displacement may always be matched: a flow that shears the surface needs the mesh to
        # slip as fast as it moves (mesh_ale shape), and with the bounded speed alone the area ALE fell behind on the
        # S = 2224 case (bound in 62 steps, triangle strain 2.4e-2; 9.1e-3 with this). Both parts shrink with dt
        cap = self.max_step * self.h * min(1.0, float(scale))
        cap += self.follow * float(np.sqrt((dXn**2).sum(axis=1)).max())
        if wmax > cap:  # a large tangential step would fold triangles on a wrinkled surface
            w *= cap / wmax
            self.capped += 1
        self.calls += 1
        self.seconds += time.perf_counter() - t0
        return topo.xp.asarray(w)

    def _extra_rows(self, X, dX, T):
        """Further least-squares rows (matrix on the 2V tangential unknowns, right-hand side): none here."""
        return ()


def damped_least_squares(A, b, damp, order=None):
    """-> argmin_u |A u - b|^2 + damp^2 |u|^2, by a sparse factorisation of its normal equations
    (A^T A + damp^2 I) u = A^T b (symmetric positive definite: no pivoting), eliminating the unknowns in ``order``
    (:func:`elimination_order`; None: SuperLU's minimum degree on this matrix). The exact minimiser is a smooth
    function of A and b, where a Krylov iterate stopped short of it is not (AreaALE). Its round-off is cond(A^T A)
    ~ (sigma_max / damp)^2 ~ 5e5 times eps; at 9512 vertices the factors hold ~2.5e6 entries."""
    import scipy.sparse as sps
    import scipy.sparse.linalg as spla

    A = sps.csr_matrix(A)
    normal = (A.T @ A + damp**2 * sps.identity(A.shape[1], format="csr")).tocsc()
    rhs = A.T @ np.asarray(b, dtype=float)
    opts = {"diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}}
    if order is None:
        return spla.splu(normal, permc_spec="MMD_AT_PLUS_A", **opts).solve(rhs)
    u = np.empty_like(rhs)
    u[order] = spla.splu(normal[order][:, order].tocsc(), permc_spec="NATURAL", **opts).solve(rhs[order])
    return u


def elimination_order(faces, n_vertices):
    """A fill-reducing order of the ALE's 2V tangential unknowns (two per vertex): SuperLU's minimum degree on the
    pattern of its normal equations, the vertex adjacency (a triangle's rows couple its three corners) in 2 x 2
    blocks. From the faces alone, so that every call, and a resumed run's first, factorises in the same order (the
    same round-off: a resume is bit for bit the uninterrupted run)."""
    import scipy.sparse as sps
    import scipy.sparse.linalg as spla

    f = np.asarray(faces, dtype=np.int64)
    i, j = np.repeat(f, 3, axis=1).ravel(), np.tile(f, (1, 3)).ravel()  # vertex pairs sharing a triangle
    rows = (2 * i[:, None] + np.array([0, 0, 1, 1])).ravel()
    cols = (2 * j[:, None] + np.array([0, 1, 0, 1])).ravel()
    n = 2 * int(n_vertices)
    pattern = sps.csc_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    # made strictly diagonally dominant (so positive definite): a matrix SuperLU factorises on that pattern
    pattern = (pattern + sps.diags(np.asarray(pattern.sum(axis=1)).ravel() + 1.0)).tocsc()
    lu = spla.splu(pattern, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return np.argsort(lu.perm_c)


def tangent_basis(X, faces):
    """(3V, 2V) sparse: two orthonormal tangent vectors per vertex (normal to the vertex normal), so that a tangential
    vertex displacement is T @ (its two components)."""
    import scipy.sparse as sps

    from ..geometry.surface import vertex_normals

    n = vertex_normals(X, faces)
    a = np.where(np.abs(n[:, 0:1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    t1 = cross_rows(n, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = cross_rows(n, t1)
    V = X.shape[0]
    rows = np.concatenate([3 * np.arange(V)[:, None] + np.arange(3)[None, :]] * 2, axis=1).ravel()
    iv = 2 * np.arange(V)[:, None]
    cols = np.concatenate([np.repeat(iv, 3, 1), np.repeat(iv + 1, 3, 1)], axis=1).ravel()
    return sps.csr_matrix((np.concatenate([t1, t2], axis=1).ravel(), (rows, cols)), shape=(3 * V, 2 * V))


class ShapeALE(AreaALE):
    """AreaALE that also keeps the triangles' shape. Beside the area rows, every triangle asks its three edges to keep
    their reference share of its squared perimeter, s_c = l_c^2 / (l_0^2 + l_1^2 + l_2^2), with a weight ``beta``:

        beta^2 sum_t W_t sum_c |3 (ds_c[w] - (S_c - s_c(X) - ds_c[dX]))|^2,

    ds_c the linearised change, S_c the reference mesh's shares. The shares fix the triangle's angles and not its
    size, so these rows leave the area pattern to the area rows (a dilation changes no share). Holding every
    triangle's area leaves the tangential motion almost no freedom (F = 2V - 4 area rows on 2V unknowns), so under a
    shear of the surface the triangles keep their areas and lose their shape: the elongated vesicle's collapse
    (docs/history/solver.md) came from such a patch, whose stiffest bending mode set a step of 1e-6 tau. The shape
    rows are
    a Gauss-Newton step towards the reference angles (zero at the reference mesh, so no steady drift)."""

    def __init__(self, space: HarmonicSpace, h, X0, faces, beta=0.1, **kw):
        super().__init__(space, h, **kw)
        self.carries_area = True
        self.faces = np.asarray(faces, dtype=np.int64)
        self.S_ref = self._shares(np.asarray(X0, dtype=float))[1]
        self.beta = float(beta)
        self.weight = 3.0 * self.beta * np.sqrt(space.W)  # per triangle: the area rows' sqrt(A0) x strain scale
        self._pattern = self._row_pattern(np.asarray(X0).shape[0])

    def _row_pattern(self, V):
        """The shape rows' sparsity, fixed by the faces: CSR indptr and indices, and each (c, k, vertex, xyz) entry's
        slot in them (an entry for the same vertex twice in a row adds up), so a call fills in the values only."""
        import scipy.sparse as sps

        f, nF = self.faces, self.faces.shape[0]
        rows, cols = [], []
        for c in range(3):
            for k in range(3):
                for vert in ((k + 2) % 3, (k + 1) % 3):
                    rows.append(np.repeat(c * nF + np.arange(nF), 3))
                    cols.append((3 * f[:, vert][:, None] + np.arange(3)).ravel())
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        P = sps.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(3 * nF, 3 * V))
        P.sum_duplicates()
        P.sort_indices()
        # slot of each entry: the position of its (row, col) among the CSR's, whose keys are sorted
        key = rows * (3 * V) + cols
        csr_key = np.repeat(np.arange(3 * nF), np.diff(P.indptr)) * (3 * V) + P.indices
        slot = np.searchsorted(csr_key, key)
        return P.indptr, P.indices, slot, (3 * nF, 3 * V)

    def _shares(self, X):
        """-> edge vectors (3, F, 3) (e_c = x_{c+2} - x_{c+1}, opposite corner c), shares s (3, F), sum of squares."""
        f = self.faces
        e = np.stack([X[f[:, (c + 2) % 3]] - X[f[:, (c + 1) % 3]] for c in range(3)])
        l2 = (e**2).sum(axis=-1)
        tot = l2.sum(axis=0)
        return e, l2 / tot, tot

    def _extra_rows(self, X, dX, T):
        return (self._share_rows(self._shares(X), dX, T, self.weight),)

    def _share_rows(self, shares, dX, T, weight):
        """The angle rows (matrix on the tangential unknowns, right-hand side) from ``_shares``' output, each
        triangle's rows scaled by ``weight`` (F,)."""
        import scipy.sparse as sps

        e, s, tot = shares
        vals = []
        for c in range(3):  # row of share c; d s_c = sum_k (delta_ck - s_c) d(l_k^2) / tot
            for k in range(3):
                g = ((float(c == k) - s[c]) / tot * weight)[:, None] * 2.0 * e[k]  # on x_{k+2}; -g on x_{k+1}
                vals += [g.ravel(), -g.ravel()]  # the order of _row_pattern's entries
        indptr, indices, slot, shape = self._pattern
        data = np.bincount(slot, weights=np.concatenate(vals), minlength=indices.size)
        G = sps.csr_matrix((data, indices, indptr), shape=shape)
        b = (weight * (self.S_ref - s)).ravel() - G @ dX.ravel()
        return G @ T, b

    def carry(self, lipid_area, X_moved, w, held):
        """-> the lipid area each triangle carries after the mesh moved by w from X_moved (the membrane's new
        positions): the held projection of the area change w makes, W B G^-1 B^T (A(X_moved + w) - A(X_moved)),
        is lipid the triangles took along, not a strain for the tension to undo. Without it the mesh's share of
        that projection went into the next solve's right-hand side and moved the membrane (0.6% in the second
        moments of a stretched vesicle at beta 0.1). The rest of the area change (the triangle scale, which the
        tension cannot see) is the mesh's, as in AreaALE. ``held``: the held coefficients; l = 0 is left out so
        that the total lipid is conserved."""
        from ..geometry.surface import triangle_areas

        sp = self.space
        dA = triangle_areas(X_moved + w, self.faces) - triangle_areas(X_moved, self.faces)
        b = sp.B.T @ dA  # the held rows take it; the others (and l = 0: the total) get none
        b[~held | (sp.l == 0)] = 0.0
        return np.asarray(lipid_area, float) + sp.W * sp.faces(sp.G_solve(b))


#: QualityALE's ramp, in a triangle's quality over its reference quality: the angle rows are off above Q_HI and at
#: full weight below Q_LO
Q_HI, Q_LO = 0.9, 0.6


class QualityALE(ShapeALE):
    """AreaALE with ShapeALE's angle rows only where a triangle has lost its shape (``mesh_ale: quality``).

    Neither ALE alone works on every rung of the elongated vesicle (docs/history/solver.md): the area rows alone let a
    sheared patch degenerate into slivers, whose stiff bending modes collapse the step; the angle rows on every
    triangle fight the benign global stretch of an elongating shape, and the lipid they carry lets the triangle
    sizes drift by up to 100% against A0. Here triangle t's angle rows get the weight beta x ramp_t,

        ramp_t = clip((Q_HI - q_t / q0_t) / (Q_HI - Q_LO), 0, 1),

    q_t its quality now and q0_t on the reference mesh: zero while the triangle keeps 90% of its reference quality,
    full below 60%. A mesh that keeps its shape is moved as AreaALE moves it. The ramp is continuous (Lipschitz, slope
    1 / (Q_HI - Q_LO) in q_t / q0_t), and a triangle whose weight reaches zero drops rows that add nothing to the
    normal equations, so which rows are on makes w no less continuous in X than AreaALE's."""

    def __init__(self, space: HarmonicSpace, h, X0, faces, beta=0.1, q_hi=Q_HI, q_lo=Q_LO, **kw):
        super().__init__(space, h, X0, faces, beta=beta, **kw)
        if not 0.0 < q_lo < q_hi <= 1.0:
            raise ValueError(f"QualityALE: need 0 < q_lo < q_hi <= 1, got q_lo = {q_lo}, q_hi = {q_hi}")
        self.q_hi, self.q_lo = float(q_hi), float(q_lo)
        self.q_ref = self._quality(np.asarray(X0, dtype=float), self._shares(np.asarray(X0, dtype=float)))
        self.active = 0  # triangles with angle rows at the last call
        self.active_max = 0

    def _quality(self, X, shares):
        """4 sqrt(3) A / (sum of the squared edges) per triangle (1: equilateral, 0: degenerate)."""
        from ..geometry.surface import triangle_areas

        return 4.0 * np.sqrt(3.0) * triangle_areas(X, self.faces) / shares[2]

    def ramp(self, X, shares=None):
        """-> (F,) in [0, 1]: each triangle's share of the angle rows' weight."""
        r = self._quality(X, self._shares(X) if shares is None else shares) / self.q_ref
        return np.clip((self.q_hi - r) / (self.q_hi - self.q_lo), 0.0, 1.0)

    def _extra_rows(self, X, dX, T):
        shares = self._shares(X)
        ramp = self.ramp(X, shares)
        on = np.flatnonzero(ramp)
        self.active = int(on.size)
        self.active_max = max(self.active_max, self.active)
        if not self.active:
            return ()
        GT, b = self._share_rows(shares, dX, T, self.weight * ramp)
        # the other triangles' rows are zero (and so is their right-hand side): they add nothing to the normal
        # equations, and leaving them out saves their share of the products
        keep = (on[None, :] + ramp.size * np.arange(3)[:, None]).ravel()
        return ((GT[keep], b[keep]),)
