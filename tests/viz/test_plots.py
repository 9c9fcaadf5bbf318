"""Figures: every plotting and rendering function writes a non-empty image from synthetic datasets with the
layouts of spectra.nc, theory.nc, fit.nc and trajectory.nc (built here, so the figures are tested on their own)."""

import argparse

import numpy as np
import pytest
import xarray as xr

from vesicle_core.errors import ConfigError
from vesicle_core.viz import plots, render

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _png_ok(path, min_bytes=2000):
    data = open(path, "rb").read()
    return data[:8] == PNG_MAGIC and len(data) > min_bytes


def _stage_sigma(t, scale=1.0):
    """sigma(t) with the three stages: a negative plateau, an algebraic decay, recovery to positive."""
    s = np.where(t < 0.1, -1000.0, -1000.0 * (np.maximum(t, 0.1) / 0.1) ** -0.8)
    s = np.where(t > 0.9, 200.0 * (t - 0.9) / 0.1 + s * (1.0 - (t - 0.9) / 0.1), s)
    return scale * np.where(t < 0, 800.0, s)


def spectra_like(S=553.0, delta=0.116, kind="spectra", n_time=60, l_max=16, maps=True, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(-0.3 if kind == "spectra" else 0.0, 1.2, n_time)
    l = np.arange(l_max + 1)
    m = np.arange(-l_max, l_max + 1)
    growth = np.exp(np.outer(np.clip(t, 0, None), l / 2.0))
    D = 1e-6 * growth / (1 + l) ** 2
    D[:, 2] = 1.0 - 0.9 * np.exp(-((t - 0.3) / 0.15) ** 2)
    D[:, :2] = 0.0
    invalid = np.abs(m)[None, :] > l[:, None]
    u = np.sqrt(D[:, :, None] / (2 * l[None, :, None] + 1)) * np.ones((1, 1, m.size))
    u[:, invalid] = np.nan
    data = {
        "u_real": (("time", "l", "m"), u),
        "u_imag": (("time", "l", "m"), np.zeros_like(u)),
        "Delta_l": (("time", "l"), D),
        "sigma": (("time",), _stage_sigma(t) + (rng.normal(0, 5, n_time) if kind == "spectra" else 0.0)),
        "t_star": ((), 0.3),
        "l_star": ((), 7.6 if kind == "spectra" else 6.8),
        "l_peak": ((), 8.0),
        "l_max_nontrivial": ((), np.int32(l_max)),
    }
    coords = {"time": t, "l": l, "m": m}
    if kind == "spectra":
        data.update({
            "A_p_bar": (("time",), 1e-4 * np.exp(-((t - 0.4) / 0.3) ** 2)),
            "Delta_tilde_l": (("time", "l"), D * 1e-2),
            "face_tension_mean": (("time",), np.zeros(n_time)),
            "face_tension_std": (("time",), np.ones(n_time)),
            "l_star_t": (("time",), np.full(n_time, 7.6)),
        })
        if maps:
            th = (np.arange(8) + 0.5) * np.pi / 8
            ph = -np.pi + (np.arange(16) + 0.5) * 2 * np.pi / 16
            data["A_p_map"] = (("time", "theta", "phi"), 1e-2 * np.sin(3 * th)[None, :, None]
                               * np.cos(2 * ph)[None, None, :] * np.ones((n_time, 1, 1)))
            coords.update(theta=th, phi=ph)
    attrs = {"delta": delta, "S": S, "chi": 66.7, "N": 32}
    return xr.Dataset(data, coords=coords, attrs=attrs)


def fit_like():
    from vesicle_core.analysis.sweep_fits import sweep_fit_dataset

    dss = []
    for i, S in enumerate((227.0, 553.0, 1106.5, 2224.0)):
        for kind in ("spectra", "theory"):
            ds = spectra_like(S=S, kind=kind, seed=i, maps=False)
            ds["l_star"] = ((), (4.0 if kind == "spectra" else 3.3) * S**0.38 * (1 + 0.02 * (-1) ** i))
            ds.attrs["case_id"] = f"{kind}{i}"
            dss.append(ds)
    dss.append(spectra_like(S=300.0, delta=0.997, kind="theory", maps=False))  # a one-point group: no fit
    return sweep_fit_dataset(dss)


def trajectory_like(n_frames=5):
    from vesicle_core.geometry.mesh import make_vesicle

    m = make_vesicle("icosphere", level=2, axes=(1.0, 0.8, 1.0))
    v, f = m.vertices, m.faces
    t = np.linspace(-0.2, 0.6, n_frames)
    scale = 1 + 0.3 * np.exp(-t**2)
    X = np.stack([v * np.array([s, 1 / np.sqrt(s), 1 / np.sqrt(s)]) for s in scale])
    centroid = v[f].mean(axis=1)
    ft = np.stack([100 * np.sign(-tt + 0.01) * centroid[:, 1] for tt in t])
    return xr.Dataset(
        {"node_x": (("time", "n_node"), X[..., 0]), "node_y": (("time", "n_node"), X[..., 1]),
         "node_z": (("time", "n_node"), X[..., 2]),
         "face_node_connectivity": (("n_face", "n_vertex_per_face"), f.astype("i4"), {"start_index": 0}),
         "face_tension": (("time", "n_face"), ft.astype("f4")), "tension": (("time",), ft.mean(axis=1))},
        coords={"time": t}, attrs={"S": 553.0, "chi": 66.7, "N": 32, "complete": 1},
    )


# --------------------------------------------------------------------------- matplotlib figures
def test_plot_dynamics_png_and_vector(tmp_path):
    out = plots.plot_dynamics(spectra_like(), spectra_like(kind="theory"), [tmp_path / "d.png", tmp_path / "d.svg"])
    assert [p.name for p in out] == ["d.png", "d.svg"]
    assert _png_ok(tmp_path / "d.png")
    assert (tmp_path / "d.svg").read_text().lstrip().startswith("<?xml")


def test_plot_dynamics_from_files_and_single_source(tmp_path):
    sp, th = tmp_path / "spectra.nc", tmp_path / "theory.nc"
    spectra_like().to_netcdf(sp)
    spectra_like(kind="theory").to_netcdf(th)
    plots.plot_dynamics(str(sp), str(th), tmp_path / "a.pdf")
    plots.plot_dynamics(None, th, tmp_path / "pa_only.png")
    plots.plot_dynamics(sp, None, tmp_path / "ibm_only.png")
    assert (tmp_path / "a.pdf").read_bytes()[:4] == b"%PDF"
    assert _png_ok(tmp_path / "pa_only.png") and _png_ok(tmp_path / "ibm_only.png")
    with pytest.raises(ConfigError, match="format"):
        plots.plot_dynamics(sp, th, tmp_path / "x.gif")
    with pytest.raises(ConfigError, match="does not exist"):
        plots.plot_dynamics(tmp_path / "missing.nc", th, tmp_path / "x.png")


def test_plot_lstar(tmp_path):
    fit = fit_like()
    assert np.isfinite(fit.l_star_exponent.values).sum() == 2  # IBM and PA at Delta = 0.116
    plots.plot_lstar(fit, [tmp_path / "l.png", tmp_path / "l.svg"])
    plots.plot_lstar(fit, tmp_path / "peak.png", measure="l_peak", guide=False)
    assert _png_ok(tmp_path / "l.png") and _png_ok(tmp_path / "peak.png")
    with pytest.raises(ConfigError, match="measure"):
        plots.plot_lstar(fit, tmp_path / "x.png", measure="k_star")


def test_plot_wrinkles_with_and_without_maps(tmp_path):
    plots.plot_wrinkles(spectra_like(), tmp_path / "w.png")
    plots.plot_wrinkles(spectra_like(), tmp_path / "w2.png", times=[0.0, 0.6])
    plots.plot_wrinkles(spectra_like(maps=False), tmp_path / "w3.png")
    for name in ("w.png", "w2.png", "w3.png"):
        assert _png_ok(tmp_path / name)
    with pytest.raises(ConfigError, match="A_p_bar"):
        plots.plot_wrinkles(spectra_like(kind="theory"), tmp_path / "x.png")


# --------------------------------------------------------------------------- 3D renders
def test_render_views_and_snapshots_matplotlib(tmp_path):
    traj = tmp_path / "trajectory.nc"
    trajectory_like().to_netcdf(traj)
    p = render.views_from_trajectory(traj, tmp_path / "views.png", time=0.2, size=(600, 400), engine="matplotlib")
    assert _png_ok(p)
    p = render.snapshots_from_trajectory(traj, tmp_path / "snaps.png", n=3, frame_size=(150, 150),
                                         engine="matplotlib")
    assert _png_ok(p)
    with pytest.raises(ConfigError, match="view"):
        render.render_snapshots([(np.zeros((3, 3)), [1.0], "x")], [[0, 1, 2]], tmp_path / "x.png", view="up")


def test_render_views_pyvista_when_available(tmp_path):
    if not render.pyvista_works():
        pytest.skip("pyvista cannot render off-screen on this machine (render.py falls back to matplotlib)")
    ds = trajectory_like()
    v = np.stack([ds[c].isel(time=2).values for c in ("node_x", "node_y", "node_z")], axis=1)
    p = render.render_views(v, ds.face_node_connectivity.values, ds.face_tension.isel(time=2).values,
                            tmp_path / "pv.png", size=(600, 400), engine="pyvista")
    assert _png_ok(p)


def test_figures_command(tmp_path):
    from vesicle_core.cli.post import add_figures

    sp, th, fit, traj = (tmp_path / n for n in ("spectra.nc", "theory.nc", "fit.nc", "trajectory.nc"))
    spectra_like().to_netcdf(sp)
    spectra_like(kind="theory").to_netcdf(th)
    fit_like().to_netcdf(fit)
    trajectory_like().to_netcdf(traj)
    parser = argparse.ArgumentParser(prog="vesicle")
    add_figures(parser.add_subparsers(dest="command", required=True))
    runs = [
        ["dynamics", str(sp), "--theory", str(th), "-o", str(tmp_path / "d.png"), str(tmp_path / "d.svg")],
        ["lstar", str(fit), "-o", str(tmp_path / "l.png")],
        ["wrinkles", str(sp), "--times", "0", "0.3", "-o", str(tmp_path / "w.png")],
        ["views", str(traj), "--spectra", str(sp), "--engine", "matplotlib", "--size", "450", "300",
         "-o", str(tmp_path / "v.png")],
        ["snapshots", str(traj), "--n", "2", "--engine", "matplotlib", "--frame-size", "120", "120",
         "-o", str(tmp_path / "s.png")],
    ]
    for argv in runs:
        args = parser.parse_args(["figures", *argv])
        assert args.func(args) == 0
    for name in ("d.png", "l.png", "w.png", "v.png", "s.png"):
        assert _png_ok(tmp_path / name), name
    with pytest.raises(SystemExit):
        parser.parse_args(["figures", "views", str(traj), "--size", "10", "10", "-o", "x.png"])


def test_snapshot_times_gather_around_t_star():
    t = np.linspace(-0.5, 1.5, 101)
    assert render.snapshot_times(t, 6, t_star=0.2) == pytest.approx([0.0, 0.1, 0.2, 0.3, 0.4, 1.5])
    assert render.snapshot_times(t, 3) == pytest.approx([0.0, 0.75, 1.5])
    assert render.snapshot_times(np.linspace(0.1, 1.0, 10), 2) == pytest.approx([0.1, 1.0])


def test_vertex_average_keeps_smooth_fields_and_removes_alternation():
    from vesicle_core.geometry import mesh as M
    from vesicle_core.viz.render import vertex_average

    m = M.make_vesicle("icosphere", level=4, axes=(1.0, 1.0, 1.0))
    v, f = m.vertices, m.faces
    zc = v[f].mean(axis=1)[:, 2]
    # a smooth field (z) survives to within the mesh scale; a constant exactly
    assert np.abs(vertex_average(v, f, zc) - v[:, 2]).max() < 0.02
    np.testing.assert_allclose(vertex_average(v, f, np.full(len(f), 3.0)), 3.0, rtol=1e-12)
    # a random +-1 per triangle (mesh-scale noise) loses most of its amplitude
    rng = np.random.default_rng(0)
    noise = rng.choice([-1.0, 1.0], size=len(f))
    assert np.sqrt(np.mean(vertex_average(v, f, noise) ** 2)) < 0.5


def test_plot_lstar_draws_each_delta_at_its_finest_grid(tmp_path, monkeypatch):
    from vesicle_core.analysis.sweep_fits import sweep_fit_dataset

    dss = []
    for N, b in ((128, 0.20), (256, 0.36)):  # a coarse rung with a different exponent
        for i, S in enumerate((227.0, 553.0, 2224.0)):
            ds = spectra_like(S=S, kind="spectra", seed=i, maps=False)
            ds["l_star"] = ((), 4.0 * S**b)
            ds.attrs.update(case_id=f"N{N}_{i}", N=N, mesh_n_vertices=2562)
            dss.append(ds)
    figs = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, outputs, dpi=150: figs.append(fig))
    plots.plot_lstar(sweep_fit_dataset(dss), tmp_path / "l.png", guide=False)
    labels = figs[0].axes[0].get_legend_handles_labels()[1]
    assert any("N = 256" in x for x in labels) and not any("N = 128" in x for x in labels)
    assert any("0.360" in x for x in labels) and not any("0.200" in x for x in labels)
    points = [ln for ln in figs[0].axes[0].lines if ln.get_linestyle() == "None"]
    assert sum(len(ln.get_xdata()) for ln in points) == 3


def test_a_set_with_each_S_at_its_own_resolution_is_fitted_as_one(tmp_path, monkeypatch):
    """Three S at 128^3, two at 192^3 and one S on both rungs: a group (N = FINEST) takes each S at its finest rung,
    its exponent is the OLS slope over those five points, the per-resolution groups stay, and Fig. 4 draws the five
    points and that group's line, with both grids in the legend."""
    from vesicle_core.analysis.fits import fit_power_law
    from vesicle_core.analysis.sweep_fits import FINEST, sweep_fit_dataset

    dss, finest = [], {}
    runs = [(128, 227.0), (128, 553.0), (128, 2224.0), (192, 553.0), (192, 1106.5), (192, 4448.0)]
    for i, (N, S) in enumerate(runs):
        ds = spectra_like(S=S, kind="spectra", seed=i, maps=False)
        ds["l_star"] = ((), 4.0 * S**0.43 * (1.0 + 0.01 * i) * (0.9 if N == 128 else 1.0))
        ds.attrs.update(case_id=f"S{S:g}_N{N}", N=N, mesh_n_vertices=9512 if N == 128 else 21398)
        dss.append(ds)
        if N >= finest.get(S, (0, 0))[0]:
            finest[S] = (N, float(ds["l_star"]))
    fit = sweep_fit_dataset(dss)
    assert sorted(fit.group_N.values.tolist()) == [FINEST, 128, 192]
    g = int(np.flatnonzero(fit.group_N.values == FINEST)[0])
    assert int(fit.n_cases[g]) == 5
    x = np.array(sorted(finest))
    ref = fit_power_law(x, np.array([finest[S][1] for S in x]), 0.95)
    assert float(fit.l_star_exponent[g]) == pytest.approx(ref.exponent, rel=1e-12)
    assert float(fit.l_star_ci_low[g]) == pytest.approx(ref.ci_low, rel=1e-12)
    figs = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, outputs, dpi=150: figs.append(fig))
    plots.plot_lstar(fit, tmp_path / "l.png", guide=False)
    labels = figs[0].axes[0].get_legend_handles_labels()[1]
    assert any("N = 128/192" in x for x in labels)
    assert [x for x in labels if "fit" in x] == [f"IBM fit: $S^{{{ref.exponent:.3f}}}$, 95% CI [{ref.ci_low:.3f}, "
                                                 f"{ref.ci_high:.3f}]"]
    points = [ln for ln in figs[0].axes[0].lines if ln.get_linestyle() == "None"]
    assert sum(len(ln.get_xdata()) for ln in points) == 5


def test_an_ensemble_is_fitted_as_one_group_with_its_spread_per_S(tmp_path, monkeypatch):
    """Four noise seeds at three S: one fit group (kT in its key), per-S mean and sd over the seeds that equal
    numpy's, a deterministic run at the same S in a group of its own, and Fig. 4 draws the ensemble's error bars."""
    from vesicle_core.analysis.sweep_fits import sweep_fit_dataset

    dss, lstar = [], {}
    for i, S in enumerate((227.0, 553.0, 2224.0)):
        for seed in range(4):
            ds = spectra_like(S=S, kind="spectra", seed=i, maps=False)
            lstar[S, seed] = 4.0 * S**0.36 * (1 + 0.03 * (seed - 1.5))
            ds["l_star"] = ((), lstar[S, seed])
            ds.attrs.update(case_id=f"S{S:g}_n{seed}", kT=0.0405, noise_seed=seed)
            dss.append(ds)
        det = spectra_like(S=S, kind="spectra", seed=i, maps=False)
        det["l_star"] = ((), 4.0 * S**0.36)
        det.attrs["case_id"] = f"S{S:g}"
        dss.append(det)
    fit = sweep_fit_dataset(dss)
    assert sorted(fit.group_kT.values.tolist()) == [0.0, 0.0405]
    hot = int(np.flatnonzero(fit.group_kT.values == 0.0405)[0])
    assert int(fit.n_cases[hot]) == 12 and fit.l_star_exponent[hot] == pytest.approx(0.36, abs=1e-6)
    pts = np.flatnonzero(fit.point_group.values == hot)
    assert fit.point_n_seeds.values[pts].tolist() == [4, 4, 4]
    for p in pts:
        S = float(fit.point_S[p])
        v = np.array([lstar[S, s] for s in range(4)])
        assert float(fit.point_l_star_mean[p]) == pytest.approx(v.mean())
        assert float(fit.point_l_star_sd[p]) == pytest.approx(v.std(ddof=1))
    figs = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, outputs, dpi=150: figs.append(fig))
    plots.plot_lstar(fit, tmp_path / "l.png", guide=False)
    labels = figs[0].axes[0].get_legend_handles_labels()[1]
    assert any("ensemble mean +- sd (4 seeds)" in x for x in labels)


def test_an_ensemble_at_one_S_gets_its_spread_and_no_exponent(tmp_path, monkeypatch):
    """Eight seeds and the deterministic run at one S (a Kantsler-style ensemble): every group's exponent is NaN
    (there is no S dependence to fit; `vesicle fit` used to stop on 'all x values are equal', and with it the
    workflow's catalog), the point carries the mean and sd over the seeds, and Fig. 4 spans S/2..2S around the
    points instead of a log axis of zero width."""
    from vesicle_core.analysis.sweep_fits import sweep_fit_dataset

    dss, v = [], []
    for seed in range(8):
        ds = spectra_like(S=947.0, delta=0.997, kind="spectra", seed=seed, maps=False)
        v.append(16.8 * (1 + 0.02 * (seed - 3.5)))
        ds["l_star"] = ((), v[-1])
        ds.attrs.update(case_id=f"n{seed}", kT=0.0405, noise_seed=seed)
        dss.append(ds)
    dss.append(spectra_like(S=947.0, delta=0.997, kind="spectra", maps=False))
    fit = sweep_fit_dataset(dss)
    assert np.isnan(fit.l_star_exponent.values).all() and np.isnan(fit.l_peak_exponent.values).all()
    p = int(np.flatnonzero(fit.point_n_seeds.values == 8)[0])
    assert float(fit.point_l_star_sd[p]) == pytest.approx(np.std(v, ddof=1))
    figs = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, outputs, dpi=150: figs.append(fig))
    plots.plot_lstar(fit, tmp_path / "l.png")
    assert figs[0].axes[0].get_xlim() == pytest.approx((473.5, 1894.0))
