"""The paper's three pattern claims (validation/claims.py, templates/morphology_claims.md.j2): each verdict follows
its numbers, and turns when the numbers do."""

import math

import numpy as np
import pytest
import xarray as xr

from vesicle_core.validation.claims import case_row, morphology_claims
from vesicle_core.validation.report import render_section

pytest.importorskip("jinja2")


def _row(S, delta=0.116, pattern="herringbone", P=0.55, low=0.1, peanut_share=0.0, enrich=1.6, max_band=5, corr=-0.4,
         cost=0.05):
    return {"case_id": f"D{delta}_S{S}", "delta": delta, "S": S, "N": 128, "vertices": 9512, "t_star": 0.22,
            "l_star": 13.0, "k_star": 9.0, "pattern_t_star": pattern, "paper": {0.5: pattern, 1.0: "labyrinth"},
            "paper_outside": [1.46, 2.0, 2.33], "P": P, "low": low, "A": 0.0, "l_c": 12.0, "defects": 0.1,
            "polar_enrichment": enrich, "corr": corr, "max_band": max_band, "n_bands": 6, "polar_tension": -900.0,
            "equator_tension": -300.0, "peanut_share": peanut_share, "n_key": 3, "series": [],
            "wall_s": 600.0, "outline_s": 600.0 * cost * 0.7, "morphology_s": 600.0 * cost * 0.3, "cost": cost}


def _text(rows, missing=()):
    return " ".join(render_section("morphology_claims", rows, list(missing)).split())


def test_claim_1_herringbone_follows_the_classes():
    rows = [_row(227), _row(553), _row(237, delta=0.997)]
    assert "Claim 1: \"a highly disordered zigzag herringbone pattern\" **Verdict: the claim holds.**" in _text(rows)
    assert "herringbone in 3 of 3 cases, and in 1 of 1 at the experiment's Delta = 0.997" in _text(rows)
    rows[0].update(pattern_t_star="labyrinth", P=0.2)
    text = _text(rows)
    assert "herringbone pattern\" **Verdict: the claim holds in part.**" in text
    assert "(otherwise: labyrinth 1)" in text and "0.2 (Delta = 0.116, S = 227)" in text
    for r in rows:
        r["pattern_t_star"] = "ripples"
    assert "herringbone pattern\" **Verdict: the claim does not hold.**" in _text(rows)


def test_claim_2_peanut_needs_the_strong_flow_to_be_more_peanut_than_the_weak():
    rows = [_row(553, peanut_share=0.0), _row(2224, peanut_share=2 / 3), _row(237, delta=0.997),
            _row(947, delta=0.997, peanut_share=1 / 3)]
    text = _text(rows)
    assert "in strong flow **Verdict: the claim holds.**" in text
    assert "Delta = 0.116: 0% of 3 at S = 553 (low-degree fraction 0.1 at t_*) against 67% of 3 at S = 2224" in text
    rows[3]["peanut_share"] = 0.0  # Delta = 0.997: the strong flow is no more peanut than the weak
    text = _text(rows)
    assert "in strong flow **Verdict: the claim holds in part.**" in text and "so the claim does not hold there" in text
    rows[0]["peanut_share"] = 1.0  # and at 0.116 the weak flow is as peanut as the strong: nowhere
    assert "in strong flow **Verdict: the claim does not hold.**" in _text(rows)


def test_claim_3_needs_polar_energy_and_compression():
    rows = [_row(553), _row(2224)]
    text = _text(rows)
    assert "membrane is compressed\" **Verdict: the claim holds.**" in text
    assert "in 2 of 2 cases, and the wrinkle energy is anti-correlated with the local tension" in text
    assert "; both hold in 2 of 2." in text  # no elongated case: nothing said about Delta = 0.997
    rows.append(_row(947, delta=0.997))
    assert "both hold in 3 of 3, and in 1 of the 1 at the experiment's Delta = 0.997" in _text(rows)
    rows.pop()
    rows[0]["corr"] = 0.3  # wrinkles where the tension is higher: not where the membrane is compressed
    text = _text(rows)
    assert "**Verdict: the claim holds in part.**" in text and "in 1 of 2; both hold in 1 of 2" in text
    rows[1].update(max_band=0, polar_enrichment=0.8)  # the energy sits at the equator
    text = _text(rows)
    assert "compressed\" **Verdict: the claim does not hold.**" in text and "| D0.116_S2224 | 0.8 | equator |" in text
    rows[1].update(max_band=5, polar_enrichment=0.95)  # the caps are the richest band yet below their area share
    assert morphology_claims(rows)["claim3"]["n_polar"] == 1  # the first case only


def test_cost_and_missing_cases_are_stated():
    rows = [_row(553, cost=0.05), _row(2224, cost=0.18)]
    text = _text(rows, missing=["D0.116_S4448_N192_Q21398"])
    assert "1 of 2 cases are within the budget (largest share 18.0%, median 11.5%)" in text
    assert "Not yet in this section (no microscope.nc when it was generated): D0.116_S4448_N192_Q21398" in text
    rows[1]["cost"] = 0.08
    assert "2 of 2 cases are within the budget" in _text(rows)
    assert morphology_claims([]) is None


def test_case_row_reads_a_microscope_file():
    mt = np.array([0.0, 0.2, 0.5, 1.0])
    time = np.linspace(-1, 1, 101)
    mic = xr.Dataset(
        {"pattern": ("morph_time", np.array([2, 1, 5, 2], np.int8)), "is_t_star": ("morph_time", [0, 1, 0, 0]),
         "paper_time": ("morph_time", [0.0, np.nan, 0.5, 1.0]), "crest_alignment": ("morph_time", [0.1, 0.5, 0.2, 0.1]),
         "low_degree_fraction": ("morph_time", [0.1, 0.2, 0.7, 0.1]), "polar_enrichment": ("morph_time", [1.0] * 4),
         "tension_correlation": ("morph_time", [-0.1] * 4), "enrichment": (("morph_time", "band"), np.ones((4, 6))),
         "band_tension": (("morph_time", "band"), np.ones((4, 6))), "k_star": ("time", np.arange(101.0))},
        coords={"morph_time": mt, "time": time},
        attrs={"delta": 0.11600000000000676, "S": 552.999999999984, "N": 128, "wall_time_s": 1000.0,
               "microscope_wall_time_s": 30.0, "morphology_wall_time_s": 20.0, "paper_times_outside": [1.46, 2.0]})
    r = case_row("c", mic, l_star=13.3)
    assert r["S"] == 553 and r["delta"] == 0.116 and r["t_star"] == 0.2 and r["pattern_t_star"] == "herringbone"
    assert r["paper"] == {0.0: "labyrinth", 0.5: "peanut", 1.0: "labyrinth"}
    assert r["peanut_share"] == pytest.approx(1 / 4) and r["n_key"] == 4
    assert r["k_star"] == 60.0 and r["cost"] == pytest.approx(0.05) and r["P"] == 0.5
    assert [s["pattern"] for s in r["series"]] == ["labyrinth", "herringbone", "peanut", "labyrinth"]
    assert math.isnan(case_row("c", mic.drop_vars("is_t_star"))["t_star"])
    # the peanut frame (t = 0.5) without wrinkles on its outline: shown, not counted for claim 2
    mic["k_star"].values[75] = np.nan
    r = case_row("c", mic)
    assert r["paper"][0.5] == "peanut" and r["n_key"] == 3 and r["peanut_share"] == 0.0


def test_the_validation_report_includes_the_section_when_named():
    from test_validation import _ladder  # the same directory, on the path in pytest's default import mode

    from vesicle_core.validation.report import render

    text = render({"morphology_section": "validation_morphology.md"}, _ladder(15.0, 28.0))
    assert "```{include} validation_morphology.md\n```" in text
    assert text.index("{include}") < text.index("## Where this project differs from the paper")
    assert "{include}" not in render({}, _ladder(15.0, 28.0))


def test_docs_validation_includes_the_generated_section():
    """docs/validation.md is what the template renders with config/convergence.yaml's morphology_section."""
    from pathlib import Path

    import yaml

    root = Path(__file__).resolve().parents[2]
    name = yaml.safe_load((root / "config" / "convergence.yaml").read_text())["validation"]["morphology_section"]
    assert f"```{{include}} {name}\n```" in (root / "docs" / "validation.md").read_text()
