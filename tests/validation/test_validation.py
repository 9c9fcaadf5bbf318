"""Validation helpers: the periodic-box comparison (Table I), the study's numbers and the report's findings (rendered
through the templates, so every finding is checked as the report prints it)."""

import sys

import numpy as np
import pytest
import xarray as xr
from unit_run import unit_run

from vesicle_core.analysis.spectra import spectra_from_trajectory
from vesicle_core.analysis.theory import run_theory
from vesicle_core.geometry import mesh as M
from vesicle_core.solver.simulate import run
from vesicle_core.validation.box import box_comparison
from vesicle_core.validation.report import render, render_section
from vesicle_core.validation.study import collect, stage1_growth


@pytest.fixture(scope="module")
def box_runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("box")
    m = M.make_vesicle("icosphere", level=2)
    out = {}
    for N, L in ((16, 5.0), (24, 7.5)):  # same h = 0.3125
        cfg = unit_run(chi=10.0, N=N, L=L, stretch=0.2, t_end=0.2, output_every=0.05, scheme="projection", dt=2.5e-4)
        out[L] = run(m, cfg, d / f"L{L}", progress=False)
    return out


def test_identical_runs_have_zero_box_error(box_runs):
    with xr.open_dataset(box_runs[5.0]) as a:
        b = box_comparison(a.load(), a.load())
    assert b["max_shape_error"] == 0 and b["max_velocity_error"] == 0


def test_larger_box_changes_shape_little(box_runs):
    with xr.open_dataset(box_runs[5.0]) as a, xr.open_dataset(box_runs[7.5]) as b:
        r = box_comparison(a.load(), b.load())
    # 2.5 vs 3.75 diameters: the image interaction is weak but not zero
    assert 0 < r["max_shape_error"] < 0.02
    assert r["L_small"] == 5.0 and r["L_large"] == 7.5


def test_report_from_real_files(box_runs, tmp_path):
    with xr.open_dataset(box_runs[5.0]) as t:
        spec = spectra_from_trajectory(t.load(), l_max=8)
    sp = tmp_path / "spectra.nc"
    spec.to_netcdf(sp)
    th = tmp_path / "theory.nc"
    run_theory(0.116, 150.0, n_out=50, store_modes=False).to_netcdf(th)
    manifest = {"cases": [{"case_id": "c1", "group": "fine", "trajectory": str(box_runs[5.0]), "spectra": str(sp),
                           "theory": str(th)}],
                "box": {"small": str(box_runs[5.0]), "large": str(box_runs[7.5])},
                "figures": [{"path": "fig.png", "caption": "a figure"}]}
    text = render(manifest, collect(manifest))
    for word in ("Characteristic wrinkle mode", "Periodic box", "Conservation", "differs from the paper", "fig.png"):
        assert word in text
    assert np.isfinite(stage1_growth(spec)) or np.isnan(float(spec.t_star))


# --------------------------------------------------------------------------- findings follow the numbers
def _row(S, N, l_star, group="ladder", tag="ladder", **kw):
    base = dict(case_id=f"D0.116_S{S:g}_N{N}_{tag}", group=group, delta=0.116, tag=tag, delta_mesh=0.116, S=S,
                chi=1.0, N=N, L=5.0, h=5.0 / N, vertices=10 * N**2 // 6, family="quasiuniform", kernel="peskin4",
                seed_spectrum="mesh", seed_scale=1.0, sim_l_star=l_star, sim_l_peak=round(l_star) + 2,
                pa_l_star=12.4 if S < 1000 else 22.6, pa_l_peak=14, paper_pa=14 if S < 1000 else 25,
                paper_ibm=15 if S < 1000 else 28, sim_t_star=0.2, pa_t_star=0.17, growth_decades=3.0,
                max_area_drift=1e-4, max_volume_drift=1e-5, dt_gamma=1e-3, steps=300, wall_s=60.0,
                scheme="inextensible", defect_ratio=0.1)
    base.update(kw)
    return base


def _ladder(limit_553, limit_2224):
    rows = []
    for N in (64, 128, 192, 256):
        h = 5.0 / N
        for S, lim in ((553.0, limit_553), (2224.0, limit_2224)):
            rows.append(_row(S, N, lim - 4000.0 * h**2, group="fine" if N == 256 else "ladder"))
    return {"rows": rows, "fits": {}, "box": None, "relaxation": None, "cutoff": None}


def test_ladder_findings_follow_the_numbers():
    agree = render({}, _ladder(15.0, 28.0))
    assert "Resolution ladder" in agree
    assert "extrapolation 28.0 [28.0, 28.0] is within 10% of it" in agree
    far = render({}, _ladder(15.0, 40.0))
    assert "(more than 10% above it)" in far  # the extrapolated S = 2224 value now lies far above the paper's 28
    # an exact h^2 law extrapolates back to its limit
    from vesicle_core.validation.study import ladder_summary

    s = ladder_summary(_ladder(15.0, 28.0)["rows"])
    assert abs(s[2224.0]["h2"]["value"] - 28.0) < 1e-9


def test_seed_and_variation_findings():
    data = _ladder(15.0, 28.0)
    data["rows"] += [_row(2224.0, 128, 20.0, group="seed", tag="seed-thermal", seed_spectrum="thermal"),
                     _row(2224.0, 128, 16.0, group="variation", tag="kernel-roma3", kernel="roma3")]
    text = render({}, data)
    base = 28.0 - 4000.0 * (5.0 / 128) ** 2
    assert "Wrinkle seeds" in text and f"{20.0 / base - 1:+.1%}" in text
    assert "One change at a time" in text and f"kernel-roma3 {16.0 / base - 1:+.1%}" in text


# --------------------------------------------------------------------------- box: the tension and its image law
def test_image_extrapolation_recovers_the_unbounded_value():
    from vesicle_core.validation.box import image_extrapolation

    def y(L):
        return 1300.0 + 2.5e4 / L**3

    assert abs(image_extrapolation(5.0, y(5.0), 7.03125, y(7.03125)) - 1300.0) < 1e-9
    # the L^-3 law, not a linear one: a 1/L series is not recovered
    assert abs(image_extrapolation(5.0, 1300 + 100 / 5.0, 7.0, 1300 + 100 / 7.0) - 1300.0) > 5.0


def test_pa_stretch_tension_mirrors_the_reversed_tension():
    """After the reversal the PA starts from the same shape with the flow reversed: sigma(0+) = -(S + Gamma_2)/A_2,
    so the stretch value (S - Gamma_2)/A_2 differs from -sigma(0+) by 2 Gamma_2 / A_2 (eq. 12)."""
    from vesicle_core.model.modes import a_l, gamma_l
    from vesicle_core.validation.study import pa_stretch_tension

    th = run_theory(0.116, 553.0, n_out=20, store_modes=False, kT_over_kappa=1e-12)  # no thermal share of u_22
    gap = 2 * float(gamma_l(2)) / float(a_l(2))
    assert abs(pa_stretch_tension(553.0) - (-float(th.sigma.values[0]) - gap)) < 1e-9 * 1300


def test_box_tension_finding_follows_the_numbers():
    b = {"L_small": 5.0, "L_large": 7.0, "tension_small": 1544.0, "tension_large": 1416.0,
         "tension_unbounded": 1344.0, "tension_pa": 1261.0}
    text = render_section("box_tension", b)
    assert "-8.3%" in text and "larger box is closer" in text
    b.update(tension_large=1600.0)
    assert "is not closer" in render_section("box_tension", b)
    # "far more than the shape" only when the tension's change is ten times the shape difference at the reversal
    b.update(tension_large=1416.0, reversal_shape_error=1.05e-3)
    assert "far more than the shape at the reversal (1.0e-03)" in render_section("box_tension", b)
    b.update(reversal_shape_error=0.05)
    text = render_section("box_tension", b)
    assert "far more" not in text and "against a shape difference of 5.0e-02" in text


def _discussion(**d):
    from vesicle_core.validation.report import _environment

    base = {"pairs": [], "summary": {}, "relaxation": None, "decay": [], "moves": [], "moves_N": [],
            "biggest_move": None, "growth": None}
    return _environment().get_template("discussion.md.j2").render(discussion={**base, **d})


def test_discussion_sentences_follow_the_numbers():
    assert "Wrinkles grow in every quasi-spherical case: Delta_l (l >= 6) changes by 4.0 to 5.1" in _discussion(
        growth=(4.0, 5.1))
    assert "Wrinkles do not grow in every quasi-spherical case" in _discussion(growth=(-0.3, 5.1))
    damped = _discussion(relaxation={"N": 256, "ratio": 0.74, "l_res": 16, "damped": True})
    assert "the kernel still damps" in damped
    resolved = _discussion(relaxation={"N": 128, "ratio": 0.97, "l_res": 25, "damped": False})
    assert "still damps" not in resolved and "within 5% of theory" in resolved
    moves = _discussion(moves=[("mesh-fine", 0.03)], moves_N=[96], biggest_move=("mesh-fine", 0.03))
    assert "One change at a time at N = 96: mesh-fine +3.0%" in moves


def test_cost_finding_follows_the_numbers():
    rows = [_row(553, 64, 6.0, wall_s=20.0), _row(553, 256, 15.0, wall_s=3000.0), _row(2224, 256, 25.0, wall_s=3000.0)]
    text = render_section("cost", rows)
    assert "1.67 h" in text and "about 0.8 h" in text and "within a 3 h" in text and "N = 256 costs" in text
    rows += [_row(227, 256, 12.0, wall_s=9000.0), _row(4448, 256, 35.0, wall_s=9000.0)]
    assert "above a 3 h" in render_section("cost", rows)


def test_grid_pa_findings_follow_the_numbers():
    s = {"rungs": [_row(2224, 128, 16.0), _row(2224, 256, 25.0)], "pa": 22.6}
    dpa = {(2224, 128, "peskin4"): {"l_star": 14.4}, (2224, 256, "peskin4"): {"l_star": 19.9}}
    text = render_section("damped_pa", s, dpa)
    assert "1.11 (N = 128), 1.26 (N = 256)" in text and "both rise" in text
    dpa[(2224, 256, "peskin4")]["l_star"] = 14.0
    assert "do not both rise" in render_section("damped_pa", s, dpa)
    keys = ("S", "N", "a", "low", "high", "grid", "pa", "paper")  # grid: the PA on the rung's grid
    rows = [dict(zip(keys, r, strict=True)) for r in ([2224, 128, 2.67, 2.5, 2.8, 2.51, 0.92, 0.81],
                                                       [2224, 256, 1.47, 1.3, 1.6, 1.25, 0.92, 0.81])]
    text = render_section("damped_decay", rows)
    assert "+0.16 (N = 128), +0.22 (N = 256)" in text and "inside the IBM interval at 1 of 2" in text
    assert "both fall" in text
    rows[1]["grid"] = 2.9
    assert "do not fall together" in render_section("damped_decay", rows)


def test_seed_closure_with_the_grid_pa_follows_the_numbers():
    rows = [_row(553, 128, 13.9, group="ladder"),
            _row(553, 128, 11.4, group="seed", tag="seed-thermal", seed_spectrum="thermal", seed_scale=1.0)]
    dpa = {(553, 128, "peskin4"): {"l_star": 10.5, "t_star": 0.24}}
    text = render_section("seeds", rows, dpa)
    # 11.4 / 10.5 - 1, 11.4 / 12.4 - 1 (the row's continuum PA), 13.9 / 10.5 - 1
    assert "+8.6% (S = 553, N = 128)" in text and "continuum PA by -8.1%" in text and "by +32.4%" in text


def test_exponent_finding_compares_with_the_grid_pa():
    Ss = (227.0, 553.0, 1106.5, 2224.0, 4448.0)
    fine = [_row(S, 256, 6.0 * S**0.33, group="fine") for S in Ss]
    dpa = {(S, 256, "peskin4"): {"l_star": 6.0 * S**0.34} for S in Ss}
    dpa.update({(S, 512, "peskin4"): {"l_star": 3.0 * S**0.45} for S in Ss})
    text = render_section("exponents", fine, {}, None, dpa)
    assert "b = 0.330" in text and "outside this interval" in text  # exact power law: a zero-width interval
    assert "The PA on the same grid gives 0.340, outside" in text and "paper's grid it gives 0.450" in text
    assert "does not contain the paper's IBM" in text


def test_cost_names_resumed_runs_whose_earlier_calls_were_not_timed():
    from vesicle_core.validation.study import _wall

    assert _wall({"wall_time_s": 90.0, "wall_time_s_last_call": 30.0, "resumed": 1}) == \
        {"wall_s": 90.0, "wall_partial": False}
    old = _wall({"wall_time_s_last_call": 30.0, "resumed": 1})
    assert old == {"wall_s": 30.0, "wall_partial": True}
    rows = [_row(553, 256, 15.0, **old), _row(2224, 256, 25.0, wall_s=60.0)]
    text = render_section("cost", rows)
    assert "D0.116_S553_N256_ladder" in text and "at least" in text and "whether it fits is open" in text
    assert "Resumed runs" not in render_section("cost", rows[1:])


def test_local_decay_brackets_the_fitted_exponent():
    """A least-squares slope over a window is a weighted mean of the local slopes in it, so the fitted stage-2
    exponent must lie between the local exponent's extremes over the same window."""
    from vesicle_core.analysis.sweep_fits import case_decay
    from vesicle_core.validation.study import local_decay

    th = run_theory(0.116, 2224.0, store_modes=False)
    fit = case_decay(th, "theory")
    loc = local_decay(th, "theory", paper=0.8108)
    assert loc["a_min"] <= fit.exponent <= loc["a_max"]
    assert loc["t_stage1_end"] < loc["t_start"] < loc["t_end"]
    assert loc["a_min_from_stage1"] <= loc["a_min"]
    assert loc["t_paper"] is None or loc["t_stage1_end"] <= loc["t_paper"] <= loc["t_end"]


def test_local_decay_finding_follows_the_numbers():
    base = {"t_stage1_end": 0.02, "t_start": 0.05, "t_end": 0.17, "a_min_from_stage1": 0.2, "paper": 0.81}
    pa = {**base, "a_min": 0.86, "a_max": 1.21, "t_paper": 0.03}
    run = {**base, "a_min": 1.0, "a_max": 1.05, "t_paper": None}
    summary = {2224.0: {"rungs": [{"N": 128, "local_decay": {}}, {"N": 256, "local_decay": run}]}}
    md = render_section("local_decay", {("PA", 2224.0): pa}, summary)
    assert "this PA: the local exponent varies by a factor 1.41" in md and "0.030, before the window" in md
    assert "IBM, N = 256: the local exponent is constant within 10%" in md and "never equals" in md
    assert render_section("local_decay", {}, {}) == ""


def test_local_decay_clause_follows_the_numbers():
    def clause(v):
        return render_section("local_decay_clause", v)

    v = {"a_min": 0.86, "a_max": 1.21, "t_paper": 0.03}
    assert "factor 1.41" in clause(v) and "0.030" in clause(v)
    assert "does not matter" in clause({**v, "a_max": 0.9})
    assert "passes" not in clause({**v, "t_paper": None})
    assert clause({}) == "" and clause(None) == ""


def test_a_value_the_templates_name_and_the_data_lack_fails_loudly():
    """StrictUndefined: a missing number raises instead of printing an empty cell."""
    import jinja2

    from vesicle_core.validation.report import _environment

    b = {"L_small": 5.0, "L_large": 7.0}
    with pytest.raises(jinja2.UndefinedError):  # the context lacks the large box's tension and the rest
        _environment().get_template("box_tension.md.j2").render(box_tension={"b": b, "small": 1544.0})


def test_the_report_without_jinja2_names_the_extra(monkeypatch):
    from vesicle_core.errors import MissingDependency
    from vesicle_core.validation.report import _environment

    _environment.cache_clear()
    monkeypatch.setitem(sys.modules, "jinja2", None)  # import jinja2 now raises ImportError
    try:
        with pytest.raises(MissingDependency, match=r"\[workflow\]"):
            render_section("cost", [])
    finally:
        _environment.cache_clear()
