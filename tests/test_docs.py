"""The documentation's own checks that need no Sphinx: no dated-log markers in the pages, and every recorded number
that a page quotes equals its one home, docs/measurements.yaml (the site build, with warnings as errors, checks the
links and anchors; .ci/run runs it)."""

from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
M = yaml.safe_load((ROOT / "docs" / "measurements.yaml").read_text())
DJ, PC, MC = M["default_job"], M["paper_converged"], M["microscope_cost"]
MP = M["microscope_cost_paper_set"]


def _f(values, digits=2):
    """The recorded values as pages write them: l_* to 0.01, exponents to 0.001."""
    return [f"{v:.{digits}f}" for v in values]


def _pct(a, b):
    return f"{100 * (a / b - 1):+.1f}%"


def _text(page):
    # line breaks do not matter, nor Markdown's escapes (l_\* keeps two l_* of a paragraph from becoming emphasis)
    return " ".join((ROOT / page).read_text().replace("\\*", "*").split())


#: (page, what it must state): the statements that quote a recorded number
QUOTES = [
    ("README.md", "l_* = {}, {}, {} at S = 553, 1106.5, 2224".format(*_f(DJ["l_star"]))),
    ("README.md", f"({DJ['wall_with_install_s']} s"),
    ("README.md", "l_* ~ S^{} [{}, {}]".format(*_f([PC["exponent"], *PC["interval"]], 3))),
    ("README.md", f"{PC['wall_min']} min"),
    ("docs/explanation/method.md", "The default job's l_* at 128^3 are {}, {} and {}".format(*_f(DJ["l_star"]))),
    ("docs/explanation/method.md", "against {}, {} and {} at 192^3".format(*_f(DJ["l_star_192"]))),
    ("docs/explanation/method.md", "between the frames {}, {} and {}".format(*_f(DJ["l_star_between_frames"]))),
    ("docs/explanation/method.md",
     "({}, {}, {})".format(*(_pct(a, b) for a, b in zip(DJ["l_star"], DJ["l_star_192"], strict=True)))),
    ("docs/explanation/method.md", "S^{} [{}, {}]".format(*_f([PC["exponent"], *PC["interval"]], 3))),
    ("docs/explanation/method.md", f"against the PA's {PC['pa_exponent']:.3f}"),
    ("docs/explanation/method.md", "IBM {}, {}; PA {}, {}".format(
        *_f([DJ["l_star"][0], DJ["l_star"][2], DJ["pa_l_star"][0], DJ["pa_l_star"][2]]))),
    ("docs/howto/reproduce-paper.md", "exponent of {} [{}, {}]".format(*_f([PC["exponent"], *PC["interval"]], 3))),
    ("docs/howto/reproduce-paper.md", f"against the paper's {PC['paper_ibm_exponent']}"),
    *[("docs/explanation/microscopy.md", f"| {c} | {w} | {b} | {o} | {m} | {bp:.2f}% | {ap:.2f}% |")
      for c, w, b, o, m, bp, ap in zip(MC["cases"], MC["run_wall_s"], MC["before_s"], MC["after_outline_s"],
                                       MC["after_morphology_s"], MC["before_share_pct"], MC["after_share_pct"],
                                       strict=True)],
    ("docs/explanation/microscopy.md", "{} s before, {} s after".format(*MC["outline_ab_s"])),
    *[("docs/explanation/microscopy.md", f"| {c} | {w} | {o} | {m} | {sh:.2f}% |")
      for c, w, o, m, sh in zip(MP["cases"], MP["run_wall_s"], MP["outline_s"], MP["morphology_s"], MP["share_pct"],
                                strict=True)],
    ("docs/explanation/microscopy.md", f"The largest share is {max(MP['share_pct']):.2f}%, within the 10% budget"),
]


@pytest.mark.parametrize(("page", "statement"), QUOTES)
def test_page_quotes_the_recorded_number(page, statement):
    assert " ".join(statement.split()) in _text(page), f"{page} should state {statement!r} (docs/measurements.yaml)"


def test_the_recorded_cost_shares_are_the_times_over_the_run():
    for w, b, o, m, bp, ap in zip(MC["run_wall_s"], MC["before_s"], MC["after_outline_s"], MC["after_morphology_s"],
                                  MC["before_share_pct"], MC["after_share_pct"], strict=True):
        assert round(100 * b / w, 2) == bp and round(100 * (o + m) / w, 2) == ap


def test_the_paper_set_cost_shares_are_the_times_over_the_run():
    for w, o, m, sh in zip(MP["run_wall_s"], MP["outline_s"], MP["morphology_s"], MP["share_pct"], strict=True):
        assert round(100 * (o + m) / w, 2) == sh


def test_the_recorded_percentages_are_computed_not_copied():
    assert _pct(13.27, 12.98) == "+2.2%"  # the helper itself, on a value worked by hand


def test_no_dated_log_markers_in_the_docs():
    pages = [p for p in (ROOT / "docs").rglob("*.md") if "_build" not in p.parts]
    offenders = [str(p.relative_to(ROOT)) for p in pages if "a later session" in p.read_text().lower()]
    assert not offenders, f"date these entries instead of 'a later session': {offenders}"


def test_the_default_jobs_cost_has_one_home():
    """config/README.md used to state its own minutes for the default job (8), README another (12)."""
    text = _text("config/README.md")
    assert "about 8 min" not in text


def test_config_readme_has_no_relative_links():
    """config/README.md is included into docs/reference/configuration.md, where a link relative to config/ breaks:
    it names docs pages as plain paths instead."""
    import re

    assert not re.findall(r"\]\((?!https?:)[^)]*\)", (ROOT / "config" / "README.md").read_text())
