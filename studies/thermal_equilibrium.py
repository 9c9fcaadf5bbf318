"""Equilibrium shape spectrum and mode autocorrelation times of a noisy IBM run without flow (chi = 0).

    python studies/thermal_equilibrium.py TRAJECTORY.nc [--burn-in 0.2] [--l-max L] > numbers.md

Make the run with ``vesicle run`` (chi: 0, stretch: 0, scheme: inextensible, kT > 0; docs/history/thermal.md section 6
gives the configuration used). Every frame after the burn-in fraction is decomposed (``harmonics.decompose``,
the pn rule, the nominal Delta of the run) into u_lm up to ``--l-max`` (default: the mesh's resolvable l, capped
at 16). Printed per l:

* <|u_lm|^2> (frames and m averaged) over kT / (kappa Delta [l(l+1) + sigma_bar]), sigma_bar the run's mean
  tension over the same frames (the trajectory's ``tension``), with the standard error of 8 time blocks;
  In a fixed-tension run (``tension_fixed``) sigma_bar is that prescribed tension, not a measured mean;
* the same at the tension the mode feels, <sigma |u_l|^2> / <|u_l|^2> over the frames (the power-weighted
  tension; it exceeds the plain mean when the constraint's tension correlates with the amplitudes);
* one tension sigma_fit fitted to the whole spectrum (least squares in log <|u_lm|^2>, l >= 2, the prefactor
  kT / (kappa Delta) fixed) and the ratios at it: whether the spectrum has the equilibrium form at some tension,
  whatever the run's recorded tension is;
* the spectrum a correct sampler of this mesh's own energy would give at sigma_bar
  (``validation.mode_energy.equilibrium_spectrum``: the piecewise-flat mesh makes short modes cheaper than the
  continuum), against the formula and against the run: what is left is the dynamics (noise, constraint, step);
* the autocorrelation time of Re/Im u_lm (m > 0): the lag at which the normalised autocorrelation, averaged over
  m, first falls below 1/e (interpolated), against the deterministic relaxation time of the same discretisation,
  1 / (r_l A_l [l(l+1) + sigma_bar]), with r_l the resolution table's rate ratio measured on the run's own N, L,
  mesh size, kernel and coupling (``validation.relaxation.mode_rate``, clean interface), and for reference with
  the fitted damping law (theory.grid_damping, fitted at an edge of ~2h). The autocorrelation is resolved only
  where it is several frames long: make the frames dense (output_every ~ 2 steps).

Feeds docs/history/thermal.md, "7. The IBM at equilibrium: shape spectrum, mode times, the vesicle's diffusion".
"""

from __future__ import annotations

import argparse

import numpy as np
import xarray as xr

from vesicle_core.analysis import harmonics as H
from vesicle_core.analysis.theory import grid_damping
from vesicle_core.geometry.surface import resolvable_l_max
from vesicle_core.model.modes import a_l


def spectra(ds, l_max, delta, first):
    f = ds.face_node_connectivity.values
    X = np.stack([ds.node_x.values, ds.node_y.values, ds.node_z.values], -1)
    return np.stack([H.decompose(X[k], f, l_max, delta=delta) for k in range(first, X.shape[0])])


def corr_time(x, dt, max_lag):
    """Lag where the normalised autocorrelation of the real series x (frames, k) first drops below 1/e."""
    x = x - x.mean(axis=0)
    var = (x * x).mean()
    c = [1.0] + [float((x[lag:] * x[:-lag]).mean() / var) for lag in range(1, max_lag)]
    c = np.array(c)
    below = np.flatnonzero(c < np.exp(-1))
    if not below.size:
        return np.nan
    j = below[0]
    c0, c1 = c[j - 1], c[j]
    return dt * (j - 1 + (c0 - np.exp(-1)) / (c0 - c1))


def grid_ratio(ds, l):
    """The resolution table's IBM / theory rate ratio of mode l (clean interface, one Stokes solve) on the run's own
    N, L, mesh size, kernel and coupling: the grid's damping of that mode, measured rather than fitted."""
    from vesicle_core.validation.relaxation import mode_rate

    a = ds.attrs
    return mode_rate(l, int(a["N"]), int(a["mesh_n_vertices"]), L=float(a["L"]), membrane="clean",
                     kernel=str(a.get("kernel", "peskin4")), coupling=str(a.get("coupling", "kernel")),
                     seed=int(a.get("mesh_seed", 0))).ratio


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("trajectory")
    ap.add_argument("--burn-in", type=float, default=0.2, help="fraction of frames skipped")
    ap.add_argument("--l-max", type=int, default=None)
    ap.add_argument("--no-mesh-equilibrium", action="store_true",
                    help="skip the mesh's own equilibrium spectrum (a V x V Hessian: ~8 s at 642 vertices)")
    a = ap.parse_args()
    ds = xr.open_dataset(a.trajectory)
    kT, delta = float(ds.attrs["kT"]), float(ds.attrs.get("mesh_target_delta", ds.attrs["delta"]))
    f = ds.face_node_connectivity.values
    X0 = np.stack([ds.node_x.values[0], ds.node_y.values[0], ds.node_z.values[0]], -1)
    L = a.l_max or min(16, resolvable_l_max(X0, f))
    first = int(a.burn_in * ds.sizes["time"])
    u = spectra(ds, L, delta, first)
    t = ds.t_tau.values[first:]
    sig = ds.tension.values[first:]
    fixed = ds.attrs.get("tension_fixed")  # "default" when the area is held (RunConfig.as_attrs: netCDF has no null)
    fixed = None if fixed is None or str(fixed) == "default" else fixed
    sbar = float(fixed) if fixed is not None else float(sig.mean())
    h = float(ds.attrs["L"]) / int(ds.attrs["N"])
    r = grid_damping(np.arange(L + 1), h, str(ds.attrs.get("kernel", "peskin4")), str(ds.attrs.get("coupling",
                                                                                                     "kernel")))
    dt_frame = float(np.median(np.diff(t)))
    print(f"run: {a.trajectory}; kT/kappa = {kT:g}, Delta = {delta:g}, N = {ds.attrs['N']}, "
          f"{ds.sizes['n_node']} vertices, frames {u.shape[0]} over t = {t[0]:.2f} .. {t[-1]:.2f} tau "
          f"(every {dt_frame:.4g} tau); {'fixed tension' if fixed is not None else 'held area'}, sigma_bar "
          f"{sbar:.1f}; recorded tension mean {sig.mean():.1f}, sd over frames {sig.std():.1f}; area drift at the "
          f"end {float(ds.area_drift.values[-1]):.2e}, volume drift {float(ds.volume_drift.values[-1]):.2e}")
    print()
    print("| l | <|u_lm|^2> | kT/(kappa Delta (l(l+1)+sigma_bar)) | ratio | se | autocorr. time [tau] "
          "| r_l measured | 1/(r_l A_l (l(l+1)+sigma_bar)) | ratio | same with the fitted r_l |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    blocks = np.array_split(np.arange(u.shape[0]), 8)
    eff, means = [], []
    for l in range(2, L + 1):
        p = np.abs(u[:, l, L - l: L + l + 1]) ** 2
        mean = float(p.mean())
        means.append(mean)
        # the tension the mode feels: its frames weighted by the mode's power (the constraint pulls hardest when
        # the modes are large, so this exceeds the plain mean when tension and amplitude correlate)
        pf = p.sum(axis=1)
        s_eff = float((sig * pf).sum() / pf.sum())
        eff.append((l, s_eff, mean / (kT / (delta * (l * (l + 1) + s_eff)))))
        se = float(np.std([p[b].mean() for b in blocks], ddof=1) / np.sqrt(len(blocks)))
        th = kT / (delta * (l * (l + 1) + sbar))
        xs = np.concatenate([u[:, l, L + 1: L + l + 1].real, u[:, l, L + 1: L + l + 1].imag], axis=1)
        tc = corr_time(xs, dt_frame, max(4, u.shape[0] // 4))
        tl = 1.0 / (r[l] * float(a_l(l)) * (l * (l + 1) + sbar))
        rl = grid_ratio(ds, l)
        tm = 1.0 / (rl * float(a_l(l)) * (l * (l + 1) + sbar))
        print(f"| {l} | {mean:.4e} | {th:.4e} | {mean / th:.3f} | {se / th:.3f} | {tc:.4g} | {rl:.3f} | {tm:.4g} "
              f"| {tc / tm:.2f} | {tl:.4g} |")
    print()
    print("| l | power-weighted tension <sigma |u_l|^2> / <|u_l|^2> | ratio at that tension |")
    print("|---|---|---|")
    for l, s_eff, r_eff in eff:
        print(f"| {l} | {s_eff:.1f} | {r_eff:.3f} |")
    ls = np.arange(2, L + 1)
    s_fit, ratio = fit_tension(ls, np.array(means), kT / delta)
    print()
    print(f"one tension fitted to the spectrum (l = 2..{L}): sigma_fit = {s_fit:.0f} (sigma_bar {sbar:.0f}); "
          f"max |ratio - 1| = {np.abs(ratio - 1).max():.3f}, at l = 3..{L - 2}: {np.abs(ratio[1:-2] - 1).max():.3f}")
    print()
    print("| l | " + " | ".join(str(l) for l in ls) + " |")
    print("|---|" + "---|" * ls.size)
    print("| ratio at sigma_fit | " + " | ".join(f"{x:.3f}" for x in ratio) + " |")
    if not a.no_mesh_equilibrium:
        mesh_equilibrium_rows(X0, f, sbar, kT, L, delta, np.array(means))


def mesh_equilibrium_rows(X0, f, sigma, kT, L, delta, means):
    """The spectrum a correct sampler of this mesh's own energy gives at sigma (validation.mode_energy), against
    the continuum formula and against the run."""
    from vesicle_core.validation.mode_energy import continuum_spectrum, equilibrium_spectrum

    ls = np.arange(2, L + 1)
    pred = equilibrium_spectrum(X0, f, sigma, kT, L, delta)[0][2:]
    print()
    print(f"this mesh's own equilibrium at sigma = {sigma:.0f} (its energy E_b + sigma A, normal displacements, "
          "through the same estimator; validation.mode_energy.equilibrium_spectrum):")
    print()
    print("| l | " + " | ".join(str(l) for l in ls) + " |")
    print("|---|" + "---|" * ls.size)
    print("| mesh equilibrium / formula | " + " | ".join(
        f"{x:.3f}" for x in pred / continuum_spectrum(ls, sigma, kT, delta)) + " |")
    print("| run / mesh equilibrium | " + " | ".join(f"{x:.3f}" for x in means / pred) + " |")


def fit_tension(l, mean, kT_over_delta):
    """The one tension at which kT / (kappa Delta (l(l+1) + sigma)) fits the spectrum best (least squares in the
    log), and the ratios spectrum / formula at it."""
    from scipy.optimize import minimize_scalar

    l = np.asarray(l, float)

    def cost(s):
        return float(np.sum(np.log(mean * (l * (l + 1) + s) / kT_over_delta) ** 2))

    s = float(minimize_scalar(cost, bounds=(-5.0, 1e5), method="bounded").x)
    return s, mean * (l * (l + 1) + s) / kT_over_delta


if __name__ == "__main__":
    main()
