"""The ``vesicle`` command: mesh | run | decompose | theory | fit | bench.

Every step of the Snakemake workflow calls one of these subcommands, so each can also be run by
hand. Bad arguments exit with status 2 and a message that names the argument and its allowed range.
"""

from __future__ import annotations

import argparse
import os
import sys

from .cli_args import int_in as _int_in
from .errors import ConfigError, NumericalInstability, VesicleError, check_range


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's default prints usage; keep that, and name the command
        self.print_usage(sys.stderr)
        self.exit(2, f"{self.prog}: error: {message}\n")


def _positive_float(name):
    def conv(s):
        try:
            v = float(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number > 0, got {s!r}") from None
        if not v > 0:
            raise argparse.ArgumentTypeError(f"{name} must be > 0, got {s!r}")
        return v

    return conv


# --------------------------------------------------------------------------- mesh
def _add_mesh(sub):
    p = sub.add_parser("mesh", help="build an ellipsoidal vesicle mesh and write it as netCDF (UGRID)")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    # defaults, ranges and help from the parameter table, as the workflow's mesh section has them
    from .parameters import MESH

    def table_arg(flag, **kw):
        q = MESH[flag.lstrip("-").replace("-", "_")]
        if q.kind == "str":
            kw.update(choices=q.choices)
        elif q.kind == "int":
            kw.update(type=_int_in(flag, int(q.lo), int(q.hi)))
        p.add_argument(flag, default=q.default, help=f"{q.help} ({q.allowed()}; default {q.default})", **kw)

    table_arg("--family")
    table_arg("--level")
    table_arg("--n-vertices")
    table_arg("--seed")
    table_arg("--lloyd-steps")
    p.add_argument("--axes", type=_positive_float("--axes"), nargs=3, metavar=("A", "B", "C"), default=(1.0, 0.8, 1.0),
                   help="axes ratio a:b:c of the ellipsoid along x, y, z, each > 0 (default 1 0.8 1)")
    p.add_argument("--delta", type=float, default=None,
                   help="target excess area Delta >= 0; solves b in 1:b:1 on this mesh (overrides --axes)")
    table_arg("--radius", type=_positive_float("--radius"))
    p.set_defaults(func=_cmd_mesh)


def _cmd_mesh(a):
    from . import mesh as M

    if a.delta is not None:
        check_range("--delta", a.delta, 0.0, 50.0)
    m = M.make_vesicle(a.family, level=a.level, axes=tuple(a.axes), R=a.radius, target_delta=a.delta,
                       n_vertices=a.n_vertices, seed=a.seed, lloyd_steps=a.lloyd_steps)
    M.save(m, a.output)
    q = m.quality()
    print(f"wrote {a.output}")
    print(f"  family {m.attrs['family']}  vertices {m.n_vertices}  faces {m.n_faces}")
    print(f"  axes {m.attrs['axes_a']:.6g}:{m.attrs['axes_b']:.6g}:{m.attrs['axes_c']:.6g}  R {a.radius:g}")
    print(f"  Delta {m.excess_area():.6f}  volume {m.volume():.6g}  area {m.area():.6g}")
    print(f"  edge min/mean/max {q['edge_min']:.4g}/{q['edge_mean']:.4g}/{q['edge_max']:.4g}  "
          f"spread {q['edge_spread']:.3f}")
    print(f"  aspect mean/max {q['aspect_mean']:.3f}/{q['aspect_max']:.3f}  angles min/max "
          f"{q['angle_min_deg']:.1f}/{q['angle_max_deg']:.1f} deg")
    return 0


# --------------------------------------------------------------------------- run
def _parse_set(items):
    import yaml

    out = {}
    for it in items or []:
        if "=" not in it:
            raise argparse.ArgumentTypeError(f"--set expects KEY=VALUE, got {it!r}")
        k, v = it.split("=", 1)
        val = yaml.safe_load(v)
        if isinstance(val, str):  # YAML 1.1 reads "2e-05" (no dot) as a string; Python writes floats that way
            try:
                val = float(val)
            except ValueError:
                pass
        out[k.strip()] = val
    return out


def _add_run(sub):
    p = sub.add_parser("run", help="simulate a vesicle in the reversed elongational flow (resumes if interrupted)")
    p.add_argument("mesh", help="mesh file written by 'vesicle mesh'")
    p.add_argument("-o", "--outdir", required=True, help="run directory (trajectory.nc, checkpoint.nc)")
    p.add_argument("-c", "--config", help="YAML file of run parameters (see vesicle_core.simulate.RunConfig)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="override one run parameter (repeatable)")
    p.add_argument("--si", metavar="YAML", help="YAML of SI parameters (units.Params: R, gamma_dot, mu, kappa, rho, "
                   "L, ...) from which chi, Re and L are derived")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=_cmd_run)


def _cmd_run(a):
    import logging

    import yaml

    from . import mesh as M
    from .errors import ConfigError
    from .run_config import RunConfig
    from .simulate import run

    logging.basicConfig(level=logging.WARNING if a.quiet else logging.INFO, format="[vesicle run] %(message)s")
    params = {}
    if a.config:
        from .run_config import load_config

        load_config(a.config)  # validates, naming the file in any error
        with open(a.config) as fh:
            params = {k: v for k, v in (yaml.safe_load(fh) or {}).items()}
    if a.si:
        from .units import Params

        with open(a.si) as fh:
            try:
                p = Params(**(yaml.safe_load(fh) or {}))
            except TypeError as exc:
                raise ConfigError(f"{a.si}: {exc}") from None
        params.update(chi=p.chi, Re=p.Re, L=p.L_bar)
    try:
        params.update(_parse_set(a.set))
    except argparse.ArgumentTypeError as exc:
        raise ConfigError(str(exc)) from None
    cfg = RunConfig.from_dict(params)  # validated before any long work starts
    mesh = M.load(a.mesh)
    path = run(mesh, cfg, a.outdir, progress=not a.quiet)
    print(f"wrote {path}")
    return 0


# --------------------------------------------------------------------------- decompose
def _add_decompose(sub):
    p = sub.add_parser("decompose", help="spherical-harmonic spectra of a trajectory (eqs. 30-32) -> spectra.nc")
    p.add_argument("trajectory", help="trajectory.nc written by 'vesicle run'")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    p.add_argument("--l-max", type=_int_in("--l-max", 2, 512), default=None,
                   help="largest degree (default: what the mesh resolves, at most 64)")
    p.add_argument("--stride", type=_int_in("--stride", 1, 10**6), default=1, help="analyse every k-th frame")
    p.add_argument("--map", type=_int_in("--map", 4, 1024), nargs=2, metavar=("NTHETA", "NPHI"), default=None,
                   help="also store A_p(theta, phi) maps on an NTHETA x NPHI grid")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_cmd_decompose)


def _cmd_decompose(a):
    from .datasets import open_trajectory, write_dataset
    from .spectra import spectra_from_trajectory

    with open_trajectory(a.trajectory, require_complete=True) as traj:
        ds = spectra_from_trajectory(traj, l_max=a.l_max, stride=a.stride, progress=not a.quiet,
                                     map_shape=tuple(a.map) if a.map else None, command=" ".join(sys.argv))
    write_dataset(ds, a.output)
    print(f"wrote {a.output}: {ds.sizes['time']} frames, l_max {ds.sizes['l'] - 1}, "
          f"t_* = {float(ds.t_star):.4g}, l_* = {float(ds.l_star):.4g}")
    return 0


# --------------------------------------------------------------------------- theory
_CF_KEYS = ("Conventions", "title", "source", "history")


def _set_cf(ds, title):
    """Replace a dataset's global attributes by the CF set plus its own parameters (the producer's
    ``source`` is kept as ``generator``)."""
    from .datasets import cf_attrs

    params = {k: v for k, v in ds.attrs.items() if k not in _CF_KEYS}
    if "source" in ds.attrs:
        params.setdefault("generator", ds.attrs["source"])
    ds.attrs = cf_attrs(title, **params)


def _add_theory(sub):
    p = sub.add_parser("theory", help="perturbation analysis (eqs. 11-12) of the same case -> theory.nc")
    p.add_argument("--delta", type=_positive_float("--delta"), required=True, help="excess area Delta > 0")
    p.add_argument("--S", type=_positive_float("--S"), required=True, help="flow strength S > 0")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    p.add_argument("--l-max", type=_int_in("--l-max", 4, 400), default=None, help="largest degree (default: from S)")
    p.add_argument("--seed", type=_int_in("--seed", 0, 2**31 - 1), default=0, help="seed of the thermal phases")
    p.add_argument("--n-out", type=_int_in("--n-out", 10, 100000), default=401, help="output times")
    p.add_argument("--no-modes", action="store_true", help="do not store u_lm(t) (smaller file)")
    p.set_defaults(func=_cmd_theory)


def _cmd_theory(a):
    from .datasets import write_dataset
    from .theory import run_theory

    ds = run_theory(a.delta, a.S, l_max=a.l_max, seed=a.seed, n_out=a.n_out, store_modes=not a.no_modes)
    _set_cf(ds, "perturbation analysis of a quasi-spherical vesicle after a flow reversal")
    write_dataset(ds, a.output)
    print(f"wrote {a.output}: t_* = {float(ds.t_star):.4g}, l_* (eq. 31) = {float(ds.l_star):.4g}, "
          f"l_peak = {float(ds.l_peak):.4g}")
    return 0


# --------------------------------------------------------------------------- fit
def _add_fit(sub):
    p = sub.add_parser("fit", help="power laws across a sweep: l_* ~ S^b and stage-2 tension decay -> fit.nc")
    p.add_argument("inputs", nargs="+", help="spectra.nc and/or theory.nc files")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    p.add_argument("--confidence", type=float, default=0.95, help="confidence level in (0, 1) (default 0.95)")
    p.set_defaults(func=_cmd_fit)


def _cmd_fit(a):
    from .datasets import read_dataset, write_dataset
    from .fits import sweep_fit_dataset

    check_range("--confidence", a.confidence, 0.0, 1.0, lo_open=True, hi_open=True)
    dss = []
    for path in a.inputs:
        ds = read_dataset(path, required=("l_star", "t_star", "sigma"))
        # runs live in results/runs/<case_id>/spectra.nc, PA references in results/theory/<theory_id>.nc
        parent = os.path.basename(os.path.dirname(os.path.abspath(path)))
        stem = os.path.splitext(os.path.basename(path))[0]
        ds.attrs.setdefault("case_id", stem if stem not in ("spectra", "theory") else parent)
        dss.append(ds)
    out = sweep_fit_dataset(dss, confidence=a.confidence)
    out.attrs["inputs"] = " ".join(a.inputs)
    _set_cf(out, "power-law fits across a vesicle-wrinkling sweep")
    write_dataset(out, a.output)
    for i in range(out.sizes["group"]):
        g = out.isel(group=i)
        print(f"{str(g.group_kind.values):>10} Delta={float(g.group_delta):g} n={int(g.n_cases)}: "
              f"l_* ~ S^{float(g.l_star_exponent):.3f} [{float(g.l_star_ci_low):.3f}, {float(g.l_star_ci_high):.3f}], "
              f"l_peak ~ S^{float(g.l_peak_exponent):.3f}")
    print(f"wrote {a.output}")
    return 0


# --------------------------------------------------------------------------- report (validation)
def _add_report(sub):
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
    p.set_defaults(func=_cmd_report)


def _cmd_report(a):
    import shutil
    from pathlib import Path

    from .validation import write_report

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
    }
    write_report(manifest, out)
    print(f"wrote {out}")
    return 0


# --------------------------------------------------------------------------- bench
def _add_bench(sub):
    p = sub.add_parser("bench", help="time one IBM step and its parts against the bare FFT (see vesicle_core.bench)")
    p.add_argument("--sizes", type=_int_in("--sizes", 8, 2048), nargs="+", default=[32, 64, 128], help="grid sizes N")
    p.add_argument("--levels", type=_int_in("--levels", 0, 8), nargs="+", default=[4, 5], help="icosphere levels")
    p.add_argument("--backend", choices=("numpy", "cupy", "auto"), default="numpy")
    p.add_argument("--repeats", type=_int_in("--repeats", 1, 10000), default=10)
    p.set_defaults(func=_cmd_bench)


def _cmd_bench(a):
    from .bench import main as bench_main

    bench_main(a.sizes, a.levels, a.backend, a.repeats)
    return 0


# --------------------------------------------------------------------------- params
def _add_params(sub):
    p = sub.add_parser("params", help="the run (or mesh) parameters: name, unit, allowed values, meaning, default")
    p.add_argument("--mesh", action="store_true", help="the mesh parameters instead of the run parameters")
    p.set_defaults(func=_cmd_params)


def _cmd_params(a):
    from .parameters import MESH_PARAMETERS, RUN_PARAMETERS, markdown_table

    print(markdown_table(MESH_PARAMETERS if a.mesh else RUN_PARAMETERS, with_default=True))
    return 0


# --------------------------------------------------------------------------- entry point
def _post_adders():
    from .cli_post import add_catalog, add_figures

    return [add_figures, add_catalog]


_ADDERS = [_add_mesh, _add_run, _add_decompose, _add_theory, _add_fit, _add_report, _add_bench, _add_params]


def build_parser():
    parser = _Parser(prog="vesicle", description=__doc__.splitlines()[0])
    from . import __version__

    parser.add_argument("--version", action="version", version=f"vesicle_core {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for add in _ADDERS + _post_adders():
        add(sub)
    return parser


def main(argv=None):
    # spinning OpenBLAS threads slowed the FFT 5-10x on the reference machine; the solver uses no BLAS-heavy code
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args) or 0
    except VesicleError as exc:
        print(f"vesicle {args.command}: error: {exc}", file=sys.stderr)
        return 3 if isinstance(exc, NumericalInstability) else 2


if __name__ == "__main__":
    sys.exit(main())
