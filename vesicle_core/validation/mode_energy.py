"""The mesh's own energy of a shape mode, and the equilibrium spectrum that energy implies.

A quasi-spherical vesicle at tension sigma has, in the continuum (R = 1, real orthonormal Y_lm, volume held),

    E = 1/2 sum_lm (l-1)(l+2) [kappa l(l+1) + sigma] c_lm^2,      <|u_lm|^2> = kT / (kappa Delta [l(l+1) + sigma_bar])

with u_lm = c_lm sqrt((l-1)(l+2)/Delta) the scaled amplitude of eq. (30) (docs/explanation/thermal-noise.md,
section 4). The IBM's
membrane is a triangle mesh: its bending energy (eq. 25) and its area are those of the piecewise-flat surface
through the vertices, and a mode of wavelength a few edges costs less on it than in the continuum (a P1
interpolant's Dirichlet energy falls like sinc^2(k h / 2) in 1D). Two functions measure this:

* :func:`mode_stiffness`: the second variation of the mesh's bending energy and area along r = 1 + eps Y_lm at
  fixed enclosed volume, over the continuum's kappa (l-1) l (l+1) (l+2) and (l-1)(l+2). Both tend to 1 like h^2.
* :func:`equilibrium_spectrum`: the Gaussian equilibrium of normal vertex displacements under the mesh's
  E_b + sigma A at fixed volume (the Hessian of the Lagrangian E - p V, p from the sphere's own force balance),
  pushed through the spectrum estimator ``harmonics.decompose`` (linearised). It is what a correct sampler of
  this mesh's energy gives for <|u_lm|^2>, the estimator's attenuation and aliasing included, and so separates
  the mesh's discretisation from the dynamics (noise, constraint, step) in a thermal run. Tangential vertex
  positions are held (the run's ALE keeps the triangles' areas); this is the one modelling choice.

Both work on a mesh whose vertices are projected onto the unit sphere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..analysis import harmonics as H
from ..errors import check_range
from ..geometry.surface import enclosed_volume, surface_area
from ..geometry.ylm import ylm
from ..solver.membrane import Topology, bending_energy, bending_force, geometry, volume_gradient


def _on_sphere(vertices):
    X = np.asarray(vertices, dtype=float)
    return X / np.linalg.norm(X, axis=1)[:, None]


def real_ylm(l_max, X):
    """Real orthonormal harmonics at unit vectors X (V, 3): dict (l, m) -> (V,), m < 0 the sine ones."""
    th = np.arccos(np.clip(X[:, 2], -1.0, 1.0))
    ph = np.arctan2(X[:, 1], X[:, 0])
    Y = ylm(l_max, th, ph)
    out = {}
    for l in range(l_max + 1):
        out[l, 0] = Y[l, l_max].real
        for m in range(1, l + 1):
            out[l, m] = np.sqrt(2.0) * Y[l, l_max + m].real
            out[l, -m] = np.sqrt(2.0) * Y[l, l_max + m].imag
    return out


@dataclass
class ModeStiffness:
    """Per l (from 2): the mesh's second variation over the continuum's, mean and range over m."""

    l: np.ndarray
    bending: np.ndarray
    bending_range: np.ndarray  # (n_l, 2) min, max over m
    area: np.ndarray
    area_range: np.ndarray


def mode_stiffness(vertices, faces, l_max, eps=1e-3) -> ModeStiffness:
    """Second variation of the mesh's bending energy and area along r = 1 + eps Y_lm, volume held by a uniform
    rescaling, over the continuum values kappa (l-1) l (l+1) (l+2) and (l-1)(l+2) (kappa = 1)."""
    check_range("l_max", l_max, 2, None)
    X0 = _on_sphere(vertices)
    f = np.asarray(faces, dtype=np.int64)
    topo = Topology(f, len(X0))
    V0 = enclosed_volume(X0, f)

    def energies(X):
        X = X * (V0 / enclosed_volume(X, f)) ** (1.0 / 3.0)
        return np.array([bending_energy(X, topo), surface_area(X, f)])

    e0 = energies(X0)
    Y = real_ylm(l_max, X0)
    ls = np.arange(2, l_max + 1)
    rows = []
    for l in ls:
        cont = np.array([(l - 1) * l * (l + 1) * (l + 2), (l - 1) * (l + 2)], dtype=float)
        r = [(energies(X0 * (1 + eps * Y[l, m])[:, None]) + energies(X0 * (1 - eps * Y[l, m])[:, None]) - 2 * e0)
             / eps**2 / cont for m in range(-l, l + 1)]
        rows.append(np.array(r))
    b = [r[:, 0] for r in rows]
    a = [r[:, 1] for r in rows]
    return ModeStiffness(ls, np.array([x.mean() for x in b]), np.array([[x.min(), x.max()] for x in b]),
                         np.array([x.mean() for x in a]), np.array([[x.min(), x.max()] for x in a]))


def continuum_spectrum(l, sigma, kT, delta, kappa=1.0):
    """<|u_lm|^2> = kT / (kappa Delta [l(l+1) + sigma / kappa]) of the scaled amplitudes (R = 1)."""
    l = np.asarray(l, dtype=float)
    return kT / (kappa * delta * (l * (l + 1.0) + sigma / kappa))


def _normal_hessian(X0, topo, sigma, kappa, h=1e-5):
    """Hessian of E_b + sigma A - p V in the normal displacements s_i (X = X0 + s n, n = X0 on the unit sphere),
    by central differences of the exact gradients; p from the least-squares force balance of the sphere."""
    V = len(X0)
    n = X0

    def grads(X):
        geo = geometry(X, topo)
        gE = -bending_force(X, topo, kappa, geo=geo) - sigma * geo.H  # geo.H = -dA/dX
        return gE, np.asarray(volume_gradient(X, topo)).reshape(V, 3)

    gE, gV = (g_ * n for g_ in grads(X0))
    gE, gV = gE.sum(1), gV.sum(1)
    p = float(gE @ gV / (gV @ gV))
    Hm = np.empty((V, V))
    for j in range(V):
        d = np.zeros((V, 1))
        d[j] = h
        (ep, vp), (em, vm) = grads(X0 + d * n), grads(X0 - d * n)
        Hm[:, j] = (((ep - p * vp) - (em - p * vm)) * n).sum(1) / (2 * h)
    return 0.5 * (Hm + Hm.T), gV, p


def equilibrium_spectrum(vertices, faces, sigma, kT, l_max, delta, kappa=1.0):
    """Mean over m of <|u_lm|^2>, l = 0..l_max, at the Gaussian equilibrium of the mesh's own energy (module
    docstring), measured with ``harmonics.decompose(..., delta=delta)`` about the unit sphere. Also returns the
    pressure p of the sphere's force balance (2 sigma in the continuum)."""
    check_range("sigma", sigma, 0.0, None)
    check_range("kT", kT, 0.0, None, lo_open=True)
    X0 = _on_sphere(vertices)
    f = np.asarray(faces, dtype=np.int64)
    V = len(X0)
    Hm, gV, p = _normal_hessian(X0, Topology(f, V), sigma, kappa)
    # volume and the three translations are held: the estimator's centre removes the latter
    Qc, _ = np.linalg.qr(np.column_stack([gV, X0]))
    Pf = np.eye(V) - Qc @ Qc.T
    w, U = np.linalg.eigh(Pf @ Hm @ Pf)
    U = U[:, np.abs(w) > 1e-8 * np.abs(w).max()]
    C = kT * U @ np.linalg.solve(U.T @ Hm @ U, U.T)

    def dec(X):
        return H.decompose(X, f, l_max, delta=delta, R=1.0, center=np.zeros(3)).ravel()

    base, step = dec(X0), 1e-6
    D = np.empty((base.size, V), dtype=complex)
    for j in range(V):
        d = np.zeros((V, 1))
        d[j] = step
        D[:, j] = (dec(X0 + d * X0) - base) / step
    var = np.real(np.einsum("ij,jk,ik->i", D, C, D.conj())).reshape(l_max + 1, 2 * l_max + 1)
    out = np.array([var[l, l_max - l: l_max + l + 1].mean() for l in range(l_max + 1)])
    return out, p
