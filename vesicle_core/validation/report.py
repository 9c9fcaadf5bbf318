"""Validation report (issue 6): ``write_report(manifest, out_md)`` writes docs/validation.md, the project's numbers
next to the paper's and next to theory.

The numbers come from study.py (``collect``: per-case l_*, the exponents of l_* against S next to the paper's 0.3923
(IBM) and 0.372 (PA) and Turitsyn's 1/3, stage-2 decay exponents next to the paper's 0.74 and 0.81, drift, steps
and wall time, the resolution ladder, the periodic-box test of Table I and the side studies), the decisions that
the findings state from findings.py, and the prose and the tables from the Jinja2 templates in templates/
(validation.md.j2 and one template per section). The manifest is described in study.py.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np

from . import findings, study


def _fmt(x, nd=3):
    """A number as the report prints it: nd significant digits, all digits from 10^nd, e-notation outside
    [1e-3, 1e7); '-' for None and non-finite values."""
    if x is None:
        return "-"
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if not math.isfinite(x):
        return "-"
    if x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e7):
        return f"{x:.2e}"
    if abs(x) >= 10 ** nd:  # 2224, 10242: all digits, not 2.22e+03
        return f"{x:.0f}" if x == int(x) else f"{x:.1f}"
    return f"{x:.{nd}g}"


def _cell(x):
    """A table cell: text as it is, a number through _fmt."""
    return x if isinstance(x, str) else _fmt(x)


@functools.cache
def _environment():
    """The templates' environment; jinja2 (the workflow extra) is imported here, so the core imports this module
    without it. StrictUndefined: a value the templates name and the context lacks fails instead of printing ''."""
    from ..errors import require

    jinja2 = require("jinja2", "workflow", "the validation report")
    env = jinja2.Environment(loader=jinja2.PackageLoader("vesicle_core.validation", "templates"),
                             undefined=jinja2.StrictUndefined, keep_trailing_newline=True, trim_blocks=True,
                             lstrip_blocks=True, autoescape=False)
    env.filters.update(fmt=_fmt, cell=_cell, f=format)  # f: a Python format spec, {{ x|f("+.1%") }}
    env.globals.update(PAPER_EXPONENT_IBM=study.PAPER_EXPONENT_IBM, PAPER_EXPONENT_PA=study.PAPER_EXPONENT_PA,
                       PAPER_GRID=study.PAPER_GRID)
    return env


def render(manifest, data) -> str:
    """The report's Markdown from the manifest and study.collect's data."""
    return _environment().get_template("validation.md.j2").render(findings.sections(manifest, data))


def render_section(name, *args) -> str:
    """One section alone: templates/<name>.md.j2 with the context findings.<name>(*args) (the tests' entry)."""
    return _environment().get_template(f"{name}.md.j2").render({name: getattr(findings, name)(*args)})


def _fig_lstar_vs_h(summary, path):
    """l_* against h per S of the ladder, with the two extrapolations, this PA and the paper's IBM (Figs. 3, 5)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 4.2))
    for k, (S, s) in enumerate(summary.items()):
        col = f"C{k}"
        h = np.array([r["h"] for r in s["rungs"]])
        y = np.array([r["sim_l_star"] for r in s["rungs"]])
        ax.plot(h, y, "o-", color=col, label=f"IBM, S = {S:g}")
        hh = np.linspace(0, 1.15 * np.sort(h)[:3].max(), 50)  # the fits cover the finest three rungs only
        for e, ls in ((s["h2"], "--"), (s["h1"], ":")):
            if math.isfinite(e["value"]):
                ax.plot(hh, e["value"] + e["slope"] * hh ** e["order"], ls, color=col, lw=1,
                        label=f"fit y0 + c h^{e['order']:g} (finest {e['n']})" if k == 0 else None)
                if math.isfinite(e["low"]) and e["order"] == 2:
                    ax.errorbar([0], [e["value"]], yerr=[[e["value"] - e["low"]], [e["high"] - e["value"]]],
                                color=col, capsize=4, fmt="s")
        if s["paper_ibm"]:
            ax.axhline(s["paper_ibm"], color=col, lw=0.8, alpha=0.6)
            ax.text(h.max(), s["paper_ibm"], f" paper IBM {s['paper_ibm']}", color=col, va="bottom", ha="right",
                    fontsize=8)
        ax.plot([0], [s["pa"]], "x", color=col, ms=8, label="this PA" if k == 0 else None)
    ax.set_xlabel("grid spacing h [R]")
    ax.set_ylabel("l_* (eq. 31)")
    ax.set_xlim(left=-0.002)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7)
    ax.set_title("Resolution ladder: l_* against h (L = 5 R, edge ~ 2 h)")
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def write_report(manifest, out_md) -> Path:
    """Collect the manifest's data, draw the ladder's figure next to ``out_md`` and write the report there."""
    from ..io import atomic_write_text

    data = study.collect(manifest)
    summary = study.ladder_summary(data["rows"])
    out_md = Path(out_md)
    if summary:
        figdir = out_md.parent / "figures" / out_md.stem
        figdir.mkdir(parents=True, exist_ok=True)
        _fig_lstar_vs_h(summary, figdir / "lstar_vs_h.png")
        manifest = {**manifest, "figures": [{"path": f"figures/{out_md.stem}/lstar_vs_h.png",
                                             "caption": "l_* against the grid spacing h, with the h^2 (dashed) and "
                                                        "h (dotted) extrapolations, this PA (x) and the paper's IBM "
                                                        "(lines)"}, *manifest.get("figures", [])]}
    text = render(manifest, data)
    atomic_write_text(text, out_md)
    return out_md


def write_morphology_claims(cases, out_md, missing=()) -> Path:
    """The paper's three pattern claims (templates/morphology_claims.md.j2) from ``cases``, a list of (case id,
    microscope.nc path, spectra.nc path or None), written to ``out_md`` (docs/validation_morphology.md, which
    docs/validation.md includes). ``missing``: the paper's cases not yet produced, named in the section."""
    import xarray as xr

    from ..io import atomic_write_text
    from .claims import case_row

    rows = []
    for case_id, mic_path, spec_path in cases:
        l_star = math.nan
        if spec_path:
            with xr.open_dataset(spec_path) as spec:
                l_star = float(spec["l_star"]) if "l_star" in spec else math.nan
        with xr.open_dataset(mic_path) as mic:
            rows.append(case_row(case_id, mic.load(), l_star))
    text = render_section("morphology_claims", rows, list(missing))
    out_md = Path(out_md)
    atomic_write_text(text, out_md)
    return out_md
