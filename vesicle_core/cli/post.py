"""``vesicle figures``, ``vesicle catalog`` and ``vesicle report``: the post-processing subcommands of the workflow.

Registered in :mod:`vesicle_core.cli` with ``add_figures(sub)``, ``add_catalog(sub)`` and ``add_report(sub)``; each
subcommand sets ``func`` to a function of the parsed arguments that returns 0.

    vesicle figures dynamics SPECTRA.nc [--theory THEORY.nc] -o FIG.png [FIG.svg ...]   Fig. 3/5 style
    vesicle figures lstar FIT.nc [--measure l_star|l_peak] -o FIG.png [FIG.svg]        Fig. 4
    vesicle figures wrinkles SPECTRA.nc [--times T ...] -o FIG.png [FIG.pdf]          Fig. 8 style
    vesicle figures views TRAJECTORY.nc [--spectra SPECTRA.nc | --time T] -o FIG.png   Figs. 6e/7c
    vesicle figures snapshots TRAJECTORY.nc [--times T ... | --n 6] -o FIG.png         strip over gamma_dot t
    vesicle catalog FILE.nc ... -o results/catalog.csv [--json results/catalog.json] [--parquet results/catalog.parquet]
    vesicle report --case ID GROUP TRAJECTORY SPECTRA THEORY ... -o docs/validation.md    the validation study
"""

from __future__ import annotations

import os

from .args import finite_float, int_in


def _outputs_arg(p, formats="png, svg or pdf"):
    p.add_argument("-o", "--output", nargs="+", required=True, metavar="FILE",
                   help=f"output file(s); the format follows each suffix ({formats})")


def _dpi_arg(p):
    p.add_argument("--dpi", type=int_in("--dpi", 50, 1200), default=150, help="resolution of the PNG (default 150)")


def _size_arg(p, default, flag="--size", what="the rendered grid of views"):
    p.add_argument(flag, type=int_in(flag, 64, 8000), nargs=2, metavar=("WIDTH", "HEIGHT"),
                   default=list(default), help=f"pixel size of {what} (default {default[0]} {default[1]})")


def _engine_arg(p):
    p.add_argument("--engine", choices=("auto", "pyvista", "matplotlib"), default=None,
                   help="3D engine (default: $VESICLE_RENDER or auto: pyvista off-screen if it works, else matplotlib)")


def _done(paths):
    for p in paths if isinstance(paths, (list, tuple)) else [paths]:
        print(f"wrote {p}")
    return 0


# --------------------------------------------------------------------------- figures
def _cmd_dynamics(a):
    from ..viz.plots import plot_dynamics

    return _done(plot_dynamics(a.spectra, a.theory, a.output, dpi=a.dpi, t_min=a.t_min, t_max=a.t_max))


def _cmd_lstar(a):
    from ..viz.plots import plot_lstar

    return _done(plot_lstar(a.fit, a.output, measure=a.measure, dpi=a.dpi, guide=not a.no_guide))


def _cmd_wrinkles(a):
    from ..viz.plots import plot_wrinkles

    return _done(plot_wrinkles(a.spectra, a.output, times=a.times, dpi=a.dpi))


def _png_only(outputs):
    from ..errors import ConfigError

    for o in outputs:
        if not o.lower().endswith(".png"):
            raise ConfigError(f"3D renders are written as PNG; got output {o}")


def _cmd_views(a):
    from ..viz.render import views_from_trajectory

    _png_only(a.output)
    out = [views_from_trajectory(a.trajectory, o, time=a.time, spectra=a.spectra, size=tuple(a.size),
                                 engine=a.engine) for o in a.output]
    return _done(out)


def _cmd_microscope_figure(a):
    from ..viz.microscopy import plot_microscope

    return _done(plot_microscope(a.microscope, a.trajectory, a.spectra, a.output, dpi=a.dpi, engine=a.engine))


def _cmd_snapshots(a):
    from ..viz.render import snapshots_from_trajectory

    _png_only(a.output)
    out = [snapshots_from_trajectory(a.trajectory, o, times=a.times, n=a.n, spectra=a.spectra, view=a.view,
                                     frame_size=tuple(a.frame_size), engine=a.engine) for o in a.output]
    return _done(out)


def add_figures(subparsers):
    """Register ``vesicle figures <kind>`` on the top-level subparsers."""
    p = subparsers.add_parser("figures", help="figures of the paper (Figs. 3/5, 4, 6e/7c, 8) from the datasets",
                              description="Figures from the datasets: matplotlib (Agg) line plots and heat maps, "
                                          "pyvista off-screen 3D renders (matplotlib fallback).")
    sub = p.add_subparsers(dest="figure", required=True, metavar="{dynamics,lstar,wrinkles,views,snapshots,microscope}")

    d = sub.add_parser("dynamics", help="Fig. 3/5: sigma(t), Delta_2(t), Delta_l*(t), IBM against PA, stages marked")
    d.add_argument("spectra", help="spectra.nc of a run ('vesicle decompose')")
    d.add_argument("--theory", help="theory.nc of the same (Delta, S) ('vesicle theory')")
    d.add_argument("--t-min", type=finite_float("--t-min"), default=0.0,
                   help="first time shown, gamma_dot (t - t0) (default 0: the reversal)")
    d.add_argument("--t-max", type=finite_float("--t-max"), default=None, help="last time shown (default: all)")
    _outputs_arg(d)
    _dpi_arg(d)
    d.set_defaults(func=_cmd_dynamics)

    s = sub.add_parser("lstar", help="Fig. 4: l_* against S (log-log) with fitted exponents and an S^(1/3) guide")
    s.add_argument("fit", help="fit.nc written by 'vesicle fit'")
    s.add_argument("--measure", choices=("l_star", "l_peak"), default="l_star",
                   help="l_* of eq. (31) (default) or the dominant mode at t_*")
    s.add_argument("--no-guide", action="store_true", help="omit the S^(1/3) guide")
    _outputs_arg(s)
    _dpi_arg(s)
    s.set_defaults(func=_cmd_lstar)

    w = sub.add_parser("wrinkles", help="Fig. 8: A_p(theta, phi) maps, A_p-bar(t), Delta~_l(t) heat map")
    w.add_argument("spectra", help="spectra.nc of a run (maps need 'vesicle decompose --map')")
    w.add_argument("--times", type=finite_float("--times"), nargs="+", default=None,
                   help="gamma_dot (t - t0) of the maps (default: t_*/2, t_* and 3 t_*/2)")
    _outputs_arg(w)
    _dpi_arg(w)
    w.set_defaults(func=_cmd_wrinkles)

    v = sub.add_parser("views", help="Figs. 6e/7c: six views of the membrane coloured by local tension")
    v.add_argument("trajectory", help="trajectory.nc written by 'vesicle run'")
    v.add_argument("--spectra", help="spectra.nc of the run: its t_* is the default time")
    v.add_argument("--time", type=finite_float("--time"), default=None,
                   help="gamma_dot (t - t0) of the frame (nearest; default t_*, else the last frame)")
    _size_arg(v, (1500, 1000))
    _engine_arg(v)
    _outputs_arg(v, "png")
    v.set_defaults(func=_cmd_views)

    n = sub.add_parser("snapshots", help="strip of membrane snapshots over gamma_dot t, coloured by local tension")
    n.add_argument("trajectory", help="trajectory.nc written by 'vesicle run'")
    n.add_argument("--spectra", help="spectra.nc of the run: the default times gather around its t_*")
    n.add_argument("--times", type=finite_float("--times"), nargs="+", default=None,
                   help="gamma_dot (t - t0) of the frames (nearest; default: n-1 evenly spaced from t0 to 2 t_*, "
                        "then the last frame)")
    n.add_argument("--n", type=int_in("--n", 1, 24), default=6, help="number of frames without --times (default 6)")
    n.add_argument("--view", choices=("front", "back", "left", "right", "top", "bottom"), default="front",
                   help="viewing direction (default front: along z)")
    _size_arg(n, (400, 400), "--frame-size", "each frame")
    _engine_arg(n)
    _outputs_arg(n, "png")
    n.set_defaults(func=_cmd_snapshots)

    m = sub.add_parser("microscope", help="Fig. 6 layout: microscope images above 3D views, k_*(t) beside l_*(t)")
    m.add_argument("microscope", help="microscope.nc of a run ('vesicle microscope')")
    m.add_argument("trajectory", help="trajectory.nc of the same run")
    m.add_argument("--spectra", help="spectra.nc of the run: l_*(t)")
    _engine_arg(m)
    _outputs_arg(m)
    _dpi_arg(m)
    m.set_defaults(func=_cmd_microscope_figure)
    return p


# --------------------------------------------------------------------------- catalog
def _cmd_catalog(a):
    from ..data.catalog import write_catalog

    rows = write_catalog(a.inputs, a.output, a.json, description=a.description, parquet_path=a.parquet,
                         parquet=True if a.parquet else None)
    kinds = {}
    for r in rows:
        kinds[r["kind"]] = kinds.get(r["kind"], 0) + 1
    summary = ", ".join(f"{n} {k}" for k, n in kinds.items())
    json_path = a.json or str(a.output).rsplit(".", 1)[0] + ".json"
    parquet = a.parquet or str(a.output).rsplit(".", 1)[0] + ".parquet"
    typed = f", {parquet}" if os.path.exists(parquet) else ""
    print(f"wrote {a.output} ({len(rows)} datasets: {summary}){typed} and {json_path}")
    return 0


def add_catalog(subparsers):
    """Register ``vesicle catalog`` on the top-level subparsers."""
    p = subparsers.add_parser("catalog", help="index datasets: catalog.csv (one row per file) + ESM-collection JSON",
                              description="Write a CSV catalog (kind, case id, Delta, S, chi, N, mesh level, backend, "
                                          "path, created, package version) and an esmcat JSON beside it. Paths are "
                                          "stored relative to the CSV's directory.")
    p.add_argument("inputs", nargs="+", help="netCDF datasets (meshes, trajectories, spectra, theory, fits)")
    p.add_argument("-o", "--output", required=True, help="catalog CSV to write")
    p.add_argument("--json", default=None, help="ESM-collection JSON to write (default: the CSV name with .json)")
    p.add_argument("--description", default=None, help="description stored in the JSON")
    p.add_argument("--parquet", default=None, help="typed Parquet copy of the catalog, the JSON's catalog_file "
                   "(needs pyarrow; default: the CSV name with .parquet, written when pyarrow is installed)")
    p.set_defaults(func=_cmd_catalog)
    return p


# --------------------------------------------------------------------------- report (validation)
def add_report(sub):
    p = sub.add_parser("report", help="write the validation study (docs/validation.md) from produced datasets")
    p.add_argument("-o", "--output", required=True, help="markdown file to write (figures are copied beside it)")
    p.add_argument("--case", nargs=5, action="append", required=True,
                   metavar=("CASE_ID", "GROUP", "TRAJECTORY", "SPECTRA", "THEORY"),
                   help="one case: id, group (fine | coarse | box), trajectory.nc, spectra.nc, theory.nc (repeatable)")
    p.add_argument("--fit", nargs=2, action="append", metavar=("GROUP", "FIT"), default=[],
                   help="fit.nc of the fine or coarse group (repeatable)")
    p.add_argument("--box", nargs=2, metavar=("SMALL", "LARGE"), help="trajectories of the periodic-box test")
    p.add_argument("--figure", nargs=2, action="append", metavar=("PATH", "CAPTION"), default=[],
                   help="figure to copy next to the report and embed (repeatable)")
    p.add_argument("--resolution-note", default="", help="one line on the resolution used")
    p.add_argument("--wall-time-note", default="", help="one line on how long the study took")
    p.add_argument("--morphology-section", default=None,
                   help="Markdown file, relative to the report, included as its section on the paper's pattern "
                        "claims (written by 'vesicle pattern-claims' from the paper's set)")
    p.set_defaults(func=_cmd_report)


def _cmd_report(a):
    import shutil
    from pathlib import Path

    from ..errors import ConfigError
    from ..validation.report import write_report

    out = Path(a.output)
    figdir = out.parent / "figures" / out.stem
    figdir.mkdir(parents=True, exist_ok=True)
    figures = []
    for path, caption in a.figure:
        src = Path(path)
        if not src.exists():
            raise ConfigError(f"--figure {path} does not exist")
        name = f"{src.parent.name}_{src.name}" if src.parent.name not in ("figures", "") else src.name
        shutil.copyfile(src, figdir / name)
        figures.append({"path": f"figures/{out.stem}/{name}", "caption": caption})
    manifest = {
        "title": "Validation against the reference paper",
        "resolution_note": a.resolution_note,
        "cases": [{"case_id": c, "group": g, "trajectory": t, "spectra": s, "theory": th} for c, g, t, s, th in a.case],
        "fits": dict(a.fit),
        "box": {"small": a.box[0], "large": a.box[1]} if a.box else None,
        "figures": figures,
        "discussion": [f"- {a.wall_time_note}"] if a.wall_time_note else [],
        "morphology_section": a.morphology_section,
    }
    write_report(manifest, out)
    print(f"wrote {out}")
    return 0
