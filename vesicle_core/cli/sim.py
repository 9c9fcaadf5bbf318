"""``vesicle mesh | run | bench | params``: the simulation subcommands (inputs, the IBM run, its cost, its parameters).

Registered in :mod:`vesicle_core.cli`; each ``add_<command>(sub)`` adds one subparser whose ``func`` takes the parsed
arguments and returns the exit status 0.
"""

from __future__ import annotations

import argparse

from ..errors import ConfigError, check_range
from .args import int_in, parse_set, positive_float


# --------------------------------------------------------------------------- mesh
def add_mesh(sub):
    p = sub.add_parser("mesh", help="build an ellipsoidal vesicle mesh and write it as netCDF (UGRID)")
    p.add_argument("-o", "--output", required=True, help="output netCDF file")
    # defaults, ranges and help from the parameter table, as the workflow's mesh section has them
    from ..model.parameters import MESH

    def table_arg(flag, **kw):
        q = MESH[flag.lstrip("-").replace("-", "_")]
        if q.kind == "str":
            kw.update(choices=q.choices)
        elif q.kind == "int":
            kw.update(type=int_in(flag, int(q.lo), int(q.hi)))
        kw.setdefault("default", q.default)
        p.add_argument(flag, help=f"{q.help} ({q.allowed()}; default {q.default})", **kw)

    table_arg("--family")
    # --level alone sets the quasi-uniform family's vertex count too (n_vertices null), as before its default moved
    table_arg("--level", default=None)
    table_arg("--n-vertices", default=None)
    table_arg("--seed")
    table_arg("--lloyd-steps")
    p.add_argument("--axes", type=positive_float("--axes"), nargs=3, metavar=("A", "B", "C"), default=(1.0, 0.8, 1.0),
                   help="axes ratio a:b:c of the ellipsoid along x, y, z, each > 0 (default 1 0.8 1)")
    p.add_argument("--delta", type=float, default=None,
                   help="target excess area Delta >= 0; solves b in 1:b:1 on this mesh (overrides --axes)")
    table_arg("--radius", type=positive_float("--radius"))
    p.set_defaults(func=_cmd_mesh)


def mesh_resolution(level, n_vertices):
    """(level, n_vertices) of ``vesicle mesh`` from its options (None: not given): the table's defaults, except that
    --level alone also sets the quasi-uniform family's vertex count (n_vertices null: 10 4^level + 2)."""
    from ..model.parameters import MESH

    if n_vertices is None and level is None:
        n_vertices = MESH["n_vertices"].default
    return (MESH["level"].default if level is None else level), n_vertices


def _cmd_mesh(a):
    from ..geometry import mesh as M
    if a.delta is not None:
        check_range("--delta", a.delta, 0.0, 50.0)
    a.level, a.n_vertices = mesh_resolution(a.level, a.n_vertices)
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
def add_run(sub):
    p = sub.add_parser("run", help="simulate a vesicle in the reversed elongational flow (resumes if interrupted)")
    p.add_argument("mesh", help="mesh file written by 'vesicle mesh'")
    p.add_argument("-o", "--outdir", required=True, help="run directory (trajectory.nc, checkpoint.nc)")
    p.add_argument("-c", "--config", help="YAML file of run parameters (see vesicle_core.model.run_config.RunConfig)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="override one run parameter (repeatable)")
    p.add_argument("--si", metavar="YAML", help="YAML of SI parameters (units.Params: R, gamma_dot, mu, kappa, rho, "
                   "L, ...) from which chi, Re and L are derived")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=_cmd_run)


def _cmd_run(a):
    import logging

    from ..geometry import mesh as M
    from ..io import safe_load_unique
    from ..model.run_config import RunConfig
    from ..solver.simulate import run

    logging.basicConfig(level=logging.WARNING if a.quiet else logging.INFO, format="[vesicle run] %(message)s")
    params = {}
    if a.config:
        from ..model.run_config import load_config

        load_config(a.config)  # validates, naming the file in any error
        with open(a.config) as fh:
            params = {k: v for k, v in (safe_load_unique(fh) or {}).items()}
    if a.si:
        import yaml

        from ..model.units import Params

        with open(a.si) as fh:
            try:
                p = Params(**(safe_load_unique(fh) or {}))
            except TypeError as exc:
                raise ConfigError(f"{a.si}: {exc}") from None
            except yaml.YAMLError as exc:  # a malformed file or a repeated key
                raise ConfigError(f"{a.si} is not valid YAML: {exc}") from None
        params.update(chi=p.chi, Re=p.Re, L=p.L_bar)
    try:
        params.update(parse_set(a.set))
    except argparse.ArgumentTypeError as exc:
        raise ConfigError(str(exc)) from None
    cfg = RunConfig.from_dict(params)  # validated before any long work starts
    mesh = M.load(a.mesh)
    path = run(mesh, cfg, a.outdir, progress=not a.quiet)
    print(f"wrote {path}")
    if not a.quiet:
        print(_cost_summary(path))
    return 0


def _cost_summary(path) -> str:
    """Where this call's wall time went, from the finished trajectory's statistics, and a second line with the
    whole run's steps by the limit that set them (step_limits)."""
    import xarray as xr

    from ..solver.step_limits import LIMITS, shares_line

    with xr.open_dataset(path) as ds:
        at = ds.attrs
        # every step is counted in the frame after it; a run resumed from a file of an older version lacks the counts
        counts = {k: int(ds[f"steps_{k}"].sum()) for k in LIMITS if f"steps_{k}" in ds}
    steps, wall = int(at.get("steps", 0)), float(at.get("wall_time_s_last_call", float("nan")))
    line = f"  {steps} steps, {wall:.1f} s this call ({1e3 * wall / max(steps, 1):.0f} ms per step)"
    if "stokes_solves" in at:
        line += f", {int(at['stokes_solves'])} Stokes solves"
    stokes, bending = at.get("stokes_s"), at.get("bending_stokes_s")
    # every Stokes product counted in the solves above: the step's and the tension's, and the bending limit's
    # measurement (its own part named; a trajectory of an older version lacks it)
    total = None if stokes is None else float(stokes) + float(bending or 0.0)
    parts = {"Stokes products": total, "mesh ALE": at.get("ale_s"), "local preconditioner": at.get("cg_precond_s")}
    shares = [f"{k} {100 * float(v) / wall:.0f}%" for k, v in parts.items() if v is not None and wall > 0]
    if shares and total is not None and bending is not None and wall > 0:
        shares[0] += f" ({100 * float(bending) / wall:.0f}% in the bending limit's measurement)"
    line += f"; {', '.join(shares)} of the wall time" if shares else ""
    return line + (f"\n  {shares_line(counts)}" if counts else "")


# --------------------------------------------------------------------------- bench
def add_bench(sub):
    p = sub.add_parser(
        "bench", help="time one IBM step and its parts against the bare FFT (see vesicle_core.solver.bench)"
    )
    p.add_argument("--sizes", type=int_in("--sizes", 8, 2048), nargs="+", default=[32, 64, 128], help="grid sizes N")
    p.add_argument("--levels", type=int_in("--levels", 0, 8), nargs="+", default=[4, 5], help="icosphere levels")
    p.add_argument("--backend", choices=("numpy", "cupy", "auto"), default="numpy")
    p.add_argument("--repeats", type=int_in("--repeats", 1, 10000), default=10)
    p.set_defaults(func=_cmd_bench)


def _cmd_bench(a):
    from ..solver.bench import main as bench_main

    bench_main(a.sizes, a.levels, a.backend, a.repeats)
    return 0


# --------------------------------------------------------------------------- params
def add_params(sub):
    p = sub.add_parser("params", help="the run (or mesh) parameters: name, unit, allowed values, meaning, default")
    p.add_argument("--mesh", action="store_true", help="the mesh parameters instead of the run parameters")
    p.set_defaults(func=_cmd_params)


def _cmd_params(a):
    from ..model.parameter_docs import markdown_table
    from ..model.parameters import MESH_PARAMETERS, RUN_PARAMETERS

    print(markdown_table(MESH_PARAMETERS if a.mesh else RUN_PARAMETERS, with_default=True))
    return 0
