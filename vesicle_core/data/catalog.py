"""Index of every dataset a sweep produced, and a sweep opened as one xarray object.

Identifiers
-----------
Sweep points get readable ids built from their physical parameters only (the Snakemake workflow and this
module share the builders below, so a path always tells what is in it):

    case      D0.116_S553_N32_L3        Delta, S (or ``chi67`` when the flow was given as chi), grid N, mesh
              D0.116_S553_N512_Q26070   (L<level>: icosphere; Q<n_vertices>[s<seed>]: quasi-uniform family),
              D0.116_S553_N32_L3_fine   optional tag (letters, digits, '-') for otherwise equal cases
    theory    D0.116_S553               the perturbation analysis depends on Delta and S only
    mesh      icosphere_L3_D0.116, quasiuniform_n26070_s0_D0.997

Numbers are written with ``%.6g`` (``1106.5``, ``0.116``); ``parse_case_id`` reads every form back. The ids hold
the *nominal* (configured) Delta and S; the datasets themselves record the meshed Delta, which differs from it by
~1e-13 when the mesh was built with ``--delta``.

Catalog
-------
``write_catalog`` writes ``catalog.csv`` (one row per netCDF dataset, for people), the same rows typed in
``catalog.parquet`` (when pyarrow is installed: the ``workflow`` and ``esm`` extras) and an ESM-collection JSON
beside them (esmcat 0.1.0: ``esmcat_version``, ``id``, ``description``, ``attributes``, ``assets``,
``aggregation_control``, ``catalog_file``: the Parquet file, else the CSV). Columns (:data:`COLUMNS`):

    kind              mesh | trajectory | spectra | theory | fit
    case_id           the id above (file stem for meshes, theory and fits)
    Delta, S, chi, N  nominal parameters from the id, else the dataset's attributes
    mesh_family, mesh_level, n_vertices
                      icosphere | quasiuniform, subdivision level (icosphere), vertex count; from the mesh
                      attributes (``mesh_*`` on runs), the id, the ``n_node`` dimension, or 10 4^L + 2 for an
                      icosphere of level L
    scheme, dtype, kernel, coupling, tension_space
                      run configuration of trajectories and spectra (kernel "peskin4", coupling "kernel" and
                      tension_space "triangle" for files written before those options, which always used them);
                      empty for the other kinds
    backend           numpy | cupy (runs)
    tag               the tag of the case id (the sweep group's ``tag``), empty when untagged
    path, created, package_version
    delta_mesh, l_star, t_star   where the dataset has them
    variables         the file's data variables, as a list literal (the ESM variable column)

Missing values are empty cells; integral numbers are written without ".0" (``S`` 553, not 553.0). ``path`` is
relative to the directory holding the catalog, so a results tree can be moved as a whole.

intake-esm (tested with 2025.12.12): ``intake.open_esm_datastore("results/catalog.json")`` groups the assets by
kind and case id (keys ``spectra.D0.116_S553_N32_L3``, one file each). Through the Parquet ``catalog_file`` the
columns keep their types (N, mesh_level, n_vertices int64; Delta, S, chi, delta_mesh, l_star, t_star float64;
empty cells null), so search with numbers: ``N=64``, ``S=553``; a variable by pattern:
``variables=".*'l_star'.*"``. (A catalog written without pyarrow points at the CSV, which intake-esm reads as
text: ``N="64"`` there.)
It opens the relative ``path`` from the current working directory, not from the catalog's: call
``to_dataset_dict()`` with the catalog's directory as working directory (or use :func:`open_sweep`, which resolves
the paths itself).

Sweep as one Dataset
--------------------
``open_sweep(path)`` stacks all spectra (``kind="spectra"``, default) or PA datasets (``kind="theory"``) along
the dimensions ``Delta`` and ``S`` (outer join; points not in the sweep are NaN), so
``open_sweep("results/catalog.csv").l_star.sel(S=553)`` works. Runs have different time axes, so:

* scalars (``l_star``, ``l_peak``, ``t_star``, ``l_max_nontrivial``, ...) are kept as they are;
* per-l arrays at t_* are added: ``Delta_l_at_t_star`` (and ``Delta_tilde_l_at_t_star`` for spectra);
  other per-l arrays without time are kept; ``l`` is the outer join of the runs' degrees (NaN above a run's l_max);
* time series (sigma, Delta_l, A_p_bar, l_star_t, ...) are linearly interpolated onto one common ``time``
  coordinate (``time=`` argument; default: the time axis of the run with the most frames, clipped to the
  interval every run covers); values outside a run's own time range are NaN;
* mode arrays with an ``m`` dimension (u_lm), A_p maps and geometry arrays are dropped (open a single run's file
  for those: the ``path`` variable holds its location).

Per-point metadata become variables on (Delta, S): ``case_id``, ``path``, ``chi``, ``N``, ``mesh_level``,
``n_vertices``, ``mesh_family``, ``scheme``, ``dtype``, ``kernel``, ``coupling``, ``tension_space``, ``tag``.
If two catalog rows share (Delta, S) (e.g. two grids or two meshes), select by any catalog column:
``open_sweep("results/catalog.csv", N=64, n_vertices=642)``, ``scheme="projection"``, ``tag="coarse"``. Numeric
columns compare as numbers (``n_vertices="642"`` selects 642; floats to 1e-9 relative), a list selects any of its
values, ``None`` or ``""`` selects empty cells, and ``variables="l_star"`` the files holding that variable.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ..errors import ConfigError, VesicleError
from ..model.parameters import MESH_PARAMETERS, RUN_PARAMETERS
from ..model.parameters import defaults as parameter_defaults
from ..model.resolution import DEFAULT_KERNEL  # also the kernel of files written before RunConfig.kernel existed

__all__ = [
    "COLUMNS",
    "build_catalog",
    "case_id",
    "catalog_row",
    "fmt_number",
    "mesh_id",
    "open_sweep",
    "parse_case_id",
    "read_catalog",
    "select_rows",
    "theory_id",
    "write_catalog",
]

COLUMNS = ("kind", "case_id", "Delta", "S", "chi", "N", "mesh_family", "mesh_level", "n_vertices", "scheme", "dtype",
           "kernel", "coupling", "tension_space", "backend", "tag", "path", "created", "package_version", "delta_mesh",
           "l_star", "t_star", "variables")
NUMERIC_COLUMNS = ("Delta", "S", "chi", "N", "mesh_level", "n_vertices", "delta_mesh", "l_star", "t_star")
INTEGER_COLUMNS = ("N", "mesh_level", "n_vertices")
RUN_KINDS = ("trajectory", "spectra")

KINDS = ("mesh", "trajectory", "spectra", "theory", "fit")
ESMCAT_VERSION = "0.1.0"
TAG_PATTERN = r"[A-Za-z0-9][A-Za-z0-9-]*"


class CatalogError(VesicleError, ValueError):
    """A catalog cannot be built or read, or a sweep cannot be stacked (the message says why)."""


# --------------------------------------------------------------------------- identifiers
def fmt_number(x) -> str:
    """Compact, stable text of a number for ids: %.6g without '+' in exponents (553, 1106.5, 0.116, 1e-05)."""
    x = float(x)
    if not math.isfinite(x):
        raise ConfigError(f"cannot build an id from the number {x!r}")
    if x == int(x) and abs(x) < 1e15:
        x = int(x)
        return str(x) if abs(x) < 1e6 else f"{x:.6g}".replace("e+", "e")
    return f"{x:.6g}".replace("e+", "e")


# the id functions default to the parameter table's mesh and grid (one home for defaults)
_MESH_DEFAULTS = parameter_defaults(MESH_PARAMETERS)
_RUN_DEFAULT_N = parameter_defaults(RUN_PARAMETERS)["N"]


def _mesh_part(family, level, n_vertices=None, seed=0):
    if family == "icosphere":
        return f"L{int(level)}"
    if family == "quasiuniform":
        part = f"Q{int(n_vertices)}" if n_vertices else f"QL{int(level)}"
        return part + (f"s{int(seed)}" if seed else "")
    raise ConfigError(f"mesh family must be 'icosphere' or 'quasiuniform', got {family!r}")


def case_id(delta, S=None, chi=None, N=_RUN_DEFAULT_N, family=_MESH_DEFAULTS["family"], level=_MESH_DEFAULTS["level"],
            n_vertices=None, seed=0, tag=None) -> str:
    """Id of one simulation case from its physical parameters (module docstring)."""
    if (S is None) == (chi is None):
        raise ConfigError("a case needs exactly one of S and chi")
    flow = f"S{fmt_number(S)}" if S is not None else f"chi{fmt_number(chi)}"
    out = f"D{fmt_number(delta)}_{flow}_N{int(N)}_{_mesh_part(family, level, n_vertices, seed)}"
    if tag:
        if not re.fullmatch(TAG_PATTERN, str(tag)):
            raise ConfigError(f"tag must match {TAG_PATTERN} (letters, digits, '-'), got {tag!r}")
        out += f"_{tag}"
    return out


def theory_id(delta, S, seed=0) -> str:
    """Id of a perturbation-analysis dataset: it depends on Delta, S (and the thermal seed) only."""
    return f"D{fmt_number(delta)}_S{fmt_number(S)}" + (f"_seed{int(seed)}" if seed else "")


def mesh_id(delta, family=_MESH_DEFAULTS["family"], level=_MESH_DEFAULTS["level"], n_vertices=None, seed=0,
            radius=1.0) -> str:
    """Id of a mesh: family, resolution, seed and target Delta (meshes are shared between flow strengths)."""
    if family == "icosphere":
        base = f"icosphere_L{int(level)}"
    elif family == "quasiuniform":
        nv = int(n_vertices) if n_vertices else 10 * 4 ** int(level) + 2
        base = f"quasiuniform_n{nv}_s{int(seed)}"
    else:
        raise ConfigError(f"mesh family must be 'icosphere' or 'quasiuniform', got {family!r}")
    out = f"{base}_D{fmt_number(delta)}"
    if float(radius) != 1.0:
        out += f"_R{fmt_number(radius)}"
    return out


_NUM = r"[0-9]+(?:\.[0-9]*)?(?:e-?[0-9]+)?"
_CASE_RE = re.compile(
    rf"^D(?P<delta>{_NUM})_(?:S(?P<S>{_NUM})|chi(?P<chi>{_NUM}))"
    rf"(?:_N(?P<N>[0-9]+)_(?:L(?P<level>[0-9]+)|QL(?P<qlevel>[0-9]+)(?:s(?P<qseed>[0-9]+))?"
    rf"|Q(?P<nv>[0-9]+)(?:s(?P<seed>[0-9]+))?))?"
    rf"(?:_seed(?P<theory_seed>[0-9]+))?(?:_(?P<tag>{TAG_PATTERN}))?$"
)


def parse_case_id(text: str) -> dict | None:
    """Parameters encoded in a case or theory id (None if ``text`` is not such an id).

    Returns Delta, S, chi (both filled: the missing one from :mod:`units`), N, mesh_family, mesh_level,
    n_vertices, tag; entries not encoded are None.
    """
    from ..model.units import S_from_chi, chi_from_S

    m = _CASE_RE.match(str(text))
    if not m:
        return None
    g = m.groupdict()
    delta = float(g["delta"])
    if delta <= 0:
        return None
    S = float(g["S"]) if g["S"] is not None else None
    chi = float(g["chi"]) if g["chi"] is not None else None
    if S is None:
        S = S_from_chi(chi, delta)
    else:
        chi = chi_from_S(S, delta)
    out = {"Delta": delta, "S": S, "chi": chi, "N": None, "mesh_family": None, "mesh_level": None,
           "n_vertices": None, "tag": g["tag"]}
    if g["N"] is not None:
        out["N"] = int(g["N"])
        if g["level"] is not None:
            out.update(mesh_family="icosphere", mesh_level=int(g["level"]))
        elif g["qlevel"] is not None:
            out.update(mesh_family="quasiuniform", mesh_level=int(g["qlevel"]))
        else:
            out.update(mesh_family="quasiuniform", n_vertices=int(g["nv"]))
    return out


# --------------------------------------------------------------------------- catalog rows
def _scalar_attr(attrs, *names):
    for n in names:
        if n in attrs:
            v = attrs[n]
            try:
                v = np.asarray(v).ravel()[0]
            except IndexError:
                continue
            if isinstance(v, (bytes, np.bytes_)):
                v = v.decode()
            if isinstance(v, str):
                if v.lower() in ("none", "default", ""):
                    continue
                try:
                    return float(v)
                except ValueError:
                    return v
            return v.item() if hasattr(v, "item") else v
    return None


def _kind_of(ds, path: Path) -> str:
    if "l_star_exponent" in ds.variables or "group" in ds.dims:
        return "fit"
    if "Delta_l" in ds.variables:
        return "spectra" if ("face_tension_mean" in ds.variables or "A_p_bar" in ds.variables) else "theory"
    if "node_x" in ds.variables:
        return "trajectory" if "time" in ds.dims else "mesh"
    parts = set(path.parts)
    for kind, folder in (("mesh", "meshes"), ("theory", "theory"), ("fit", "fits")):
        if folder in parts:
            return kind
    raise CatalogError(f"{path}: cannot tell which kind of dataset this is (mesh, trajectory, spectra, theory, fit)")


def _id_from_path(path: Path, kind: str) -> str:
    if kind in ("trajectory", "spectra"):
        return path.parent.name
    return path.stem


def _created(attrs, path: Path) -> str:
    hist = attrs.get("history")
    if isinstance(hist, str) and hist:
        stamp = hist.strip().split(" ", 1)[0]  # cf_attrs: "<ISO time> <command>", newest first
        try:
            return datetime.fromisoformat(stamp).isoformat(timespec="seconds")
        except ValueError:
            pass
    return datetime.fromtimestamp(path.stat().st_mtime, UTC).isoformat(timespec="seconds")


def _package_version(attrs) -> str:
    from .. import __version__

    for key in ("source", "generator"):
        src = attrs.get(key)
        if isinstance(src, str) and src.startswith("vesicle_core "):
            return src.split(" ", 1)[1].strip()
    return __version__


def _num_or_nan(v):
    try:
        v = float(v)
    except (TypeError, ValueError):
        return math.nan
    return v


def _text_attr(attrs, name):
    """A string attribute as text (None when absent or empty); unlike _scalar_attr never turned into a number."""
    if name not in attrs:
        return None
    v = attrs[name]
    if isinstance(v, (bytes, np.bytes_)):
        v = v.decode()
    v = str(v).strip()
    return v or None


def _n_vertices(ds, attrs, kind, parsed, family, level):
    """Vertex count of the mesh a dataset is on (None for theory and fits, or when nothing tells it)."""
    if kind not in ("mesh", *RUN_KINDS):
        return None
    nv = _scalar_attr(attrs, "n_vertices" if kind == "mesh" else "mesh_n_vertices")
    if nv is None:
        nv = parsed.get("n_vertices")
    if nv is None and "n_node" in ds.sizes:
        nv = ds.sizes["n_node"]
    if nv is None and family == "icosphere" and level is not None:
        nv = 10 * 4 ** int(level) + 2  # an icosphere of level L has exactly this many vertices
    nv = _num_or_nan(nv)
    return int(nv) if math.isfinite(nv) and nv > 0 else None


def catalog_row(path, root=None) -> dict:
    """One catalog row for a netCDF dataset (kind, parameters, path relative to ``root``, creation time...)."""
    import xarray as xr

    path = Path(path)
    if not path.is_file():
        raise CatalogError(f"{path}: file does not exist")
    try:
        ds = xr.open_dataset(path, engine="netcdf4")
    except (OSError, ValueError, RuntimeError) as exc:
        raise CatalogError(f"{path}: not a readable netCDF file ({exc})") from None
    with ds:
        attrs = dict(ds.attrs)
        kind = _kind_of(ds, path)
        ident = _id_from_path(path, kind)
        parsed = parse_case_id(ident) or {}
        row = {c: None for c in COLUMNS}
        row.update(kind=kind, case_id=ident)
        # nominal parameters: the id (what the sweep asked for), else the dataset's attributes
        delta_mesh = _scalar_attr(attrs, "mesh_delta", "delta_used") if kind in ("trajectory", "spectra") else None
        if kind == "mesh":
            delta_mesh = _scalar_attr(attrs, "delta")
        delta = parsed.get("Delta")
        if delta is None:
            delta = _scalar_attr(attrs, "mesh_target_delta", "target_delta", "delta")
        S = parsed.get("S")
        chi = parsed.get("chi")
        if S is None and kind != "mesh":
            S = _scalar_attr(attrs, "S")
        if chi is None and kind != "mesh":
            chi = _scalar_attr(attrs, "chi")
        N = parsed.get("N")
        if N is None and kind in ("trajectory", "spectra"):
            N = _scalar_attr(attrs, "N")
        family = parsed.get("mesh_family") or _scalar_attr(attrs, "mesh_family", "family")
        level = parsed.get("mesh_level")
        if level is None:
            lv = _scalar_attr(attrs, "mesh_level", "level")
            level = lv if lv is not None and _num_or_nan(lv) >= 0 else None
        n_vertices = _n_vertices(ds, attrs, kind, parsed, family, level)
        run = {"scheme": None, "dtype": None, "kernel": None, "coupling": None, "tension_space": None}
        if kind in RUN_KINDS:
            run = {c: _text_attr(attrs, c) for c in run}
            run["kernel"] = run["kernel"] or DEFAULT_KERNEL
            run["coupling"] = run["coupling"] or "kernel"
            run["tension_space"] = run["tension_space"] or "triangle"
        row.update(
            Delta=_num_or_nan(delta), S=_num_or_nan(S), chi=_num_or_nan(chi),
            N=int(N) if N is not None else None, mesh_family=family if kind != "theory" and kind != "fit" else None,
            mesh_level=int(level) if level is not None and kind not in ("theory", "fit") else None,
            backend=_scalar_attr(attrs, "backend") if kind in ("trajectory", "spectra") else None,
            created=_created(attrs, path), package_version=_package_version(attrs),
            delta_mesh=_num_or_nan(delta_mesh), n_vertices=n_vertices, tag=parsed.get("tag"),
            variables=repr(sorted(str(v) for v in ds.data_vars)), **run,
        )
        if kind in ("spectra", "theory"):
            for name in ("l_star", "t_star"):
                if name in ds.variables and ds[name].ndim == 0:
                    row[name] = float(ds[name].values)
    if root is not None:
        row["path"] = os.path.relpath(path.resolve(), Path(root).resolve())
    else:
        row["path"] = str(path)
    return row


def build_catalog(paths, root=None) -> list[dict]:
    """Rows for every file in ``paths`` (netCDF datasets), sorted by kind then case id."""
    rows = [catalog_row(p, root=root) for p in paths]
    order = {k: i for i, k in enumerate(KINDS)}
    rows.sort(key=lambda r: (order.get(r["kind"], 99), r["case_id"], r["path"]))
    return rows


def _fmt_cell(v):
    if v is None:
        return ""
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)
    return str(v)


def esm_collection(catalog_file: str, description: str | None = None, cid: str = "vesicle-wrinkling") -> dict:
    """ESM-collection (esmcat 0.1.0) description of a catalog table (``catalog_file``: Parquet or CSV)."""
    described = {
        "kind": "dataset kind: mesh | trajectory | spectra | theory | fit",
        "case_id": "sweep point id (D<Delta>_S<S>_N<N>_L<level>), theory id (D<Delta>_S<S>) or mesh id",
        "Delta": "nominal excess area Delta of the sweep point (1)",
        "S": "flow strength S of the perturbation analysis (1)",
        "chi": "dimensionless extensional rate gamma_dot mu R^3 / kappa (1)",
        "N": "grid nodes per axis",
        "mesh_family": "icosphere | quasiuniform",
        "mesh_level": "icosphere subdivision level",
        "n_vertices": "number of mesh vertices",
        "scheme": "time-stepping scheme of the run (projection | explicit | inextensible)",
        "dtype": "floating-point precision of the run's grid fields (float64 | float32)",
        "kernel": "regularised delta function of the run (peskin4 | roma3 | bao6)",
        "coupling": "fluid-membrane coupling of the run (kernel | sharp)",
        "tension_space": "tension space of the inextensible scheme (triangle | harmonic; triangle for the others)",
        "backend": "array backend of the run (numpy | cupy)",
        "tag": "tag of the case (its sweep group), empty when untagged",
        "path": "file location relative to the directory of this catalog",
        "created": "creation time (ISO 8601, UTC) from the dataset's history attribute",
        "package_version": "vesicle_core version that wrote the dataset",
        "delta_mesh": "excess area of the meshed surface (1)",
        "l_star": "characteristic wrinkle mode l_* of eq. (31) at t_*",
        "t_star": "t_* = argmin Delta_2, gamma_dot (t - t0)",
        "variables": "data variables of the file, as a list literal ['A_p_bar', 'Delta_l', ...]",
    }
    return {
        "esmcat_version": ESMCAT_VERSION,
        "id": cid,
        "description": description or ("Datasets of a vesicle-wrinkling sweep: meshes, IBM trajectories, spherical-"
                                        "harmonic spectra, perturbation-analysis references and power-law fits."),
        "catalog_file": catalog_file,
        "attributes": [{"column_name": c, "vocabulary": "", "description": described[c]} for c in COLUMNS
                       if c != "path"],
        "assets": {"column_name": "path", "format": "netcdf"},
        # intake-esm groups assets by these columns; without aggregation_control it would group by every column and
        # refuse the columns that are empty for some kinds (S of a mesh, ...). kind and case_id are never empty.
        "aggregation_control": {"variable_column_name": "variables", "groupby_attrs": ["kind", "case_id"],
                                "aggregations": []},
    }


def _arrow_table(rows):
    """The rows as a typed Arrow table: N, mesh_level, n_vertices int64, the other numeric columns float64 (empty
    cells null in both), text columns as strings ("" when empty), ``variables`` as the CSV's list literal."""
    import pyarrow as pa

    def column(c):
        if c in NUMERIC_COLUMNS:
            cast = int if c in INTEGER_COLUMNS else float
            values = [None if _is_empty(r[c]) else cast(r[c]) for r in rows]
            return pa.array(values, type=pa.int64() if c in INTEGER_COLUMNS else pa.float64())
        return pa.array([_fmt_cell(r[c]) for r in rows], type=pa.string())

    return pa.Table.from_arrays([column(c) for c in COLUMNS], names=list(COLUMNS))


def _write_parquet(rows, path: Path) -> None:
    import pyarrow.parquet as pq

    from ..io import _temp_beside

    tmp = _temp_beside(path)
    try:
        pq.write_table(_arrow_table(rows), tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def have_pyarrow() -> bool:
    try:
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        return False
    return True


def write_catalog(paths, csv_path, json_path=None, description=None, parquet_path=None,
                  parquet: bool | None = None) -> list[dict]:
    """Write ``csv_path`` (for people), the typed ``parquet_path`` (default: the CSV name with .parquet) and the
    ESM-collection JSON ``json_path`` (default: the CSV name with .json) for the netCDF files ``paths``. Paths in
    the catalogs are relative to their directory. Returns the rows.

    The JSON's ``catalog_file`` is the Parquet file, so intake-esm sees numbers as numbers (``N == 64``).
    ``parquet``: True needs pyarrow (``pip install -e ".[workflow]"`` or ``".[esm]"``), False writes the CSV alone
    (``catalog_file`` is then the CSV, read as text by intake-esm), None (default) writes Parquet when pyarrow is
    installed (and otherwise removes a stale Parquet catalog of the same name)."""
    from ..io import atomic_write_text

    csv_path = Path(csv_path)
    json_path = Path(json_path) if json_path else csv_path.with_suffix(".json")
    parquet_path = Path(parquet_path) if parquet_path else csv_path.with_suffix(".parquet")
    if parquet is None:
        parquet = have_pyarrow()
        if not parquet:
            parquet_path.unlink(missing_ok=True)
    elif parquet and not have_pyarrow():
        raise CatalogError(f"writing {parquet_path} needs pyarrow: pip install pyarrow (in the workflow and esm "
                           "extras), or write the CSV catalog alone")
    root = csv_path.parent.resolve()
    rows = build_catalog(paths, root=root)
    seen = {}
    for r in rows:
        if r["path"] in seen:
            raise CatalogError(f"{r['path']} listed twice")
        seen[r["path"]] = r
    import io

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for r in rows:
        w.writerow([_fmt_cell(r[c]) for c in COLUMNS])
    atomic_write_text(buf.getvalue(), csv_path)
    table = csv_path
    if parquet:
        if parquet_path.resolve().parent != root:
            raise CatalogError(f"{parquet_path}: the Parquet catalog must lie beside {csv_path} (paths are relative)")
        _write_parquet(rows, parquet_path)
        table = parquet_path
    rel = os.path.relpath(table.resolve(), json_path.resolve().parent)
    atomic_write_text(json.dumps(esm_collection(rel, description), indent=2) + "\n", json_path)
    return rows


# --------------------------------------------------------------------------- reading
def _catalog_csv(path) -> Path:
    path = Path(path)
    if path.is_dir():
        path = path / "catalog.csv"
    if path.suffix == ".json":
        try:
            meta = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise CatalogError(f"{path}: not a readable ESM-collection JSON ({exc})") from None
        if "catalog_file" not in meta:
            raise CatalogError(f"{path}: ESM-collection JSON without 'catalog_file'")
        path = (path.parent / meta["catalog_file"]).resolve()
        if path.suffix == ".parquet":  # the typed copy; the CSV beside it holds the same rows
            path = path.with_suffix(".csv")
    if not path.is_file():
        raise CatalogError(f"{path}: catalog does not exist")
    return path


def _parse_variables(text) -> tuple:
    import ast

    try:
        v = ast.literal_eval(text) if text else ()
    except (ValueError, SyntaxError):
        return ()
    return tuple(str(x) for x in v) if isinstance(v, (list, tuple, set)) else ()


def _read_catalog(path) -> tuple[Path, list[str], list[dict]]:
    """(CSV path, the columns the CSV has, rows). Columns of :data:`COLUMNS` that an older CSV lacks are filled
    with empty values in the rows (but are not in the returned column list)."""
    csv_path = _catalog_csv(path)
    rows = []
    with open(csv_path, newline="") as fh:
        reader = csv.DictReader(fh)
        header = list(reader.fieldnames or [])
        if "path" not in header:
            raise CatalogError(f"{csv_path}: not a catalog (no 'path' column; columns: {', '.join(header)})")
        for r in reader:
            out = {c: "" for c in COLUMNS}
            out.update(r)
            for c in NUMERIC_COLUMNS:
                v = out.get(c)
                if c in INTEGER_COLUMNS:
                    out[c] = int(float(v)) if v not in (None, "") else None
                else:
                    out[c] = float(v) if v not in (None, "") else math.nan
            out["variables"] = _parse_variables(out.get("variables"))
            p = Path(r["path"])
            out["abspath"] = str(p if p.is_absolute() else (csv_path.parent / p).resolve())
            rows.append(out)
    return csv_path, header, rows


def read_catalog(path) -> list[dict]:
    """Rows of a catalog (CSV, its ESM JSON, or a directory holding catalog.csv); numeric columns as numbers
    (NaN, or None for the integer columns N, mesh_level, n_vertices, when empty), ``variables`` as a tuple of
    names, text columns as strings ("" when empty), and an extra ``abspath`` with the absolute file location."""
    return _read_catalog(path)[2]


# --------------------------------------------------------------------------- selecting rows
def _is_empty(v) -> bool:
    return v is None or (isinstance(v, str) and v == "") or (isinstance(v, float) and math.isnan(v))


def _wanted_values(key, value) -> list:
    """The values one selector accepts: a scalar, or any of a list/tuple/set; numbers for numeric columns,
    None for "empty"."""
    values = list(value) if isinstance(value, (list, tuple, set, frozenset, np.ndarray)) else [value]
    out = []
    for v in values:
        if isinstance(v, np.generic):
            v = v.item()
        if _is_empty(v):
            out.append(None)
        elif key in NUMERIC_COLUMNS:
            try:
                if isinstance(v, bool):
                    raise TypeError
                out.append(float(v))
            except (TypeError, ValueError):
                raise CatalogError(f"selector {key}={v!r}: {key} is a numeric column, give a number") from None
        else:
            out.append(str(v))
    if not out:
        raise CatalogError(f"selector {key}={value!r}: give at least one value")
    return out


def _cell_matches(key, cell, wanted) -> bool:
    if key == "variables":
        return any((not cell) if w is None else (w in cell) for w in wanted)
    if key in NUMERIC_COLUMNS:
        x = _num_or_nan(cell)
        return any(math.isnan(x) if w is None else (not math.isnan(x) and math.isclose(x, w, rel_tol=1e-9))
                   for w in wanted)
    text = "" if _is_empty(cell) else str(cell)
    return any(text == ("" if w is None else w) for w in wanted)


def _pandas():
    try:
        import pandas
    except ImportError:  # xarray depends on pandas, so this is for completeness
        return None
    return pandas


def select_rows(rows, columns, where: dict, source="catalog") -> list[dict]:
    """The rows matching every selector ``column=value`` of ``where`` (semantics: module docstring).

    columns: the columns the catalog has; a selector on any other name raises CatalogError naming them.
    Filters with pandas when it is importable, else row by row (same result).
    """
    unknown = [k for k in where if k not in columns]
    if unknown:
        old = [k for k in unknown if k in COLUMNS]
        hint = (f"; {', '.join(old)} {'is a column' if len(old) == 1 else 'are columns'} of catalogs written by "
                f"this version: rebuild the catalog with 'vesicle catalog'") if old else ""
        raise CatalogError(f"unknown catalog column{'s' if len(unknown) > 1 else ''} "
                           f"{', '.join(map(repr, unknown))} in the selection; {source} has the columns: "
                           f"{', '.join(c for c in columns)}{hint}")
    wanted = {k: _wanted_values(k, v) for k, v in where.items()}
    if not rows or not wanted:
        return list(rows)
    pd = _pandas()
    if pd is None:
        return [r for r in rows if all(_cell_matches(k, r.get(k), w) for k, w in wanted.items())]
    df = pd.DataFrame({k: [r.get(k) for r in rows] for k in wanted})
    mask = np.ones(len(rows), dtype=bool)
    for key, values in wanted.items():
        col = df[key]
        hit = np.zeros(len(rows), dtype=bool)
        if key == "variables":
            for w in values:
                hit |= col.map(lambda cell, w=w: (not cell) if w is None else (w in cell)).to_numpy(dtype=bool)
        elif key in NUMERIC_COLUMNS:
            x = pd.to_numeric(col, errors="coerce").to_numpy(dtype=float)
            for w in values:
                hit |= np.isnan(x) if w is None else np.isclose(x, w, rtol=1e-9, atol=0.0)
        else:
            text = col.astype(object).where(col.notna(), "").map(str)
            for w in values:
                hit |= (text == ("" if w is None else w)).to_numpy(dtype=bool)
        mask &= hit
    return [r for r, keep in zip(rows, mask, strict=True) if keep]


_TIME_SERIES_DROP_DIMS = ("m", "theta", "phi", "axis", "principal")
# columns named in the "two datasets at one (Delta, S)" error when they tell the two apart
_SELECT_HINT_COLUMNS = ("N", "mesh_family", "mesh_level", "n_vertices", "scheme", "dtype", "kernel", "coupling",
                        "tension_space", "backend", "tag", "chi")


def _same(a, b) -> bool:
    if _is_empty(a) and _is_empty(b):
        return True
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(float(a), float(b), rel_tol=1e-9)
    return a == b


def _reduce_one(ds, time_grid, kind):
    import xarray as xr

    out = {}
    i_star = None
    t = np.asarray(ds["time"].values, dtype=float) if "time" in ds.coords else None
    if t is not None and "t_star" in ds and np.isfinite(float(ds["t_star"])):
        i_star = int(np.argmin(np.abs(t - float(ds["t_star"]))))
    for name, var in ds.data_vars.items():
        if any(d in var.dims for d in _TIME_SERIES_DROP_DIMS):
            continue
        if var.dtype.kind not in "iufb":
            continue
        if "time" not in var.dims:
            out[name] = var.astype(float)
            continue
        if name in ("Delta_l", "Delta_tilde_l") and i_star is not None:
            out[f"{name}_at_t_star"] = var.isel(time=i_star, drop=True).astype(float)
            out[f"{name}_at_t_star"].attrs = dict(var.attrs, long_name=f"{name} at t_*")
        if time_grid is not None:
            out[name] = var.astype(float).interp(time=time_grid, kwargs={"fill_value": np.nan})
    res = xr.Dataset(out)
    for c in ("t_tau",):
        if c in res.coords:
            res = res.drop_vars(c)
    return res


def _common_time(datasets, time):
    if time is not None:
        return np.asarray(time, dtype=float)
    axes = [np.asarray(ds["time"].values, dtype=float) for ds in datasets if "time" in ds.coords]
    if not axes:
        return None
    lo = max(a.min() for a in axes)
    hi = min(a.max() for a in axes)
    ref = max(axes, key=len)
    grid = ref[(ref >= lo) & (ref <= hi)]
    if grid.size < 2:
        grid = np.linspace(lo, hi, max(len(ref), 2)) if hi > lo else ref
    return grid


def open_sweep(path, kind: str = "spectra", time=None, **where):
    """All datasets of one kind in a catalog as one xarray Dataset on the sweep dimensions (Delta, S).

    path: catalog CSV, its ESM JSON, or the directory holding catalog.csv. kind: "spectra" (simulation, default)
    or "theory" (perturbation analysis). time: common time grid for the time series (default: see module
    docstring). where: selectors on any catalog column, e.g. ``N=64``, ``n_vertices=642``, ``scheme="projection"``,
    ``Delta=0.116``, ``case_id="..."``, ``tag=["coarse", ""]`` (see :func:`select_rows`); an unknown column name
    raises CatalogError listing the catalog's columns.
    """
    import xarray as xr

    if kind not in ("spectra", "theory"):
        raise CatalogError(f"open_sweep stacks 'spectra' or 'theory' datasets, got kind={kind!r}")
    csv_path, columns, rows = _read_catalog(path)
    rows = select_rows([r for r in rows if r["kind"] == kind], columns, where, source=str(csv_path))
    if not rows:
        raise CatalogError(f"{path}: no {kind} datasets" + (f" matching {where}" if where else ""))
    keys = {}
    for r in rows:
        k = (r["Delta"], r["S"])
        if k in keys:
            other = keys[k]
            differ = [c for c in _SELECT_HINT_COLUMNS if c in columns and not _same(other[c], r[c])]
            hint = (f"select one with a column where they differ: {', '.join(f'{c}=...' for c in differ)} "
                    "(or case_id=...)") if differ else "select one with case_id=..."
            raise CatalogError(f"two {kind} datasets at Delta={k[0]:g}, S={k[1]:g} ({other['case_id']} and "
                               f"{r['case_id']}); {hint}")
        keys[k] = r
    dss = []
    for r in rows:
        with xr.open_dataset(r["abspath"], engine="netcdf4") as ds:
            dss.append(ds.load())
    grid = _common_time(dss, time)
    parts = []
    for r, ds in zip(rows, dss, strict=True):
        red = _reduce_one(ds, grid, kind)
        meta = {"case_id": r["case_id"], "path": r["abspath"], "chi": r["chi"]}
        for c in INTEGER_COLUMNS:
            meta[c] = float(r[c]) if r[c] is not None else math.nan
        for c in ("mesh_family", "scheme", "dtype", "kernel", "coupling", "tension_space", "tag"):
            meta[c] = str(r[c] or "")
        for k, v in meta.items():
            red[k] = xr.DataArray(v)
        red = red.expand_dims(Delta=[r["Delta"]], S=[r["S"]])
        parts.append(red)
    out = xr.merge(parts, join="outer", compat="no_conflicts", combine_attrs="drop")
    out = out.sortby(["Delta", "S"])
    out["Delta"].attrs.update(units="1", long_name="excess area Delta (nominal)")
    out["S"].attrs.update(units="1", long_name="flow strength S")
    if "time" in out.coords:
        out["time"].attrs.update(units="1/gamma_dot", long_name="gamma_dot (t - t0), common grid (interpolated)")
    out.attrs.update(title=f"vesicle-wrinkling sweep: {kind} stacked along (Delta, S)",
                     catalog=str(_catalog_csv(path)), kind=kind,
                     time_note="time series linearly interpolated onto a common grid; NaN outside a run's range")
    return out
