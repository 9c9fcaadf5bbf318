"""Index of every dataset a sweep produced: catalog rows, the CSV/Parquet catalog and its ESM collection.

Catalog
-------
``write_catalog`` writes ``catalog.csv`` (one row per netCDF dataset, for people), the same rows typed in
``catalog.parquet`` (when pyarrow is installed: the ``workflow`` and ``esm`` extras) and an ESM-collection JSON
beside them (esmcat 0.1.0: ``esmcat_version``, ``id``, ``description``, ``attributes``, ``assets``,
``aggregation_control``, ``catalog_file``: the Parquet file, else the CSV). Columns (:data:`COLUMNS`):

    kind              mesh | trajectory | spectra | microscope | theory | fit
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
    kT, noise_seed    thermal noise of runs: k_B T / kappa (0: deterministic, also for files written before the
                      noise existed) and, when kT > 0, the noise seed (one member of an ensemble); from the id
                      (``_kT<kT>_n<seed>``), else the dataset's attributes; empty for the other kinds
    backend           numpy | cupy (runs)
    tag               the tag of the case id (the sweep group's ``tag``), empty when untagged
    path, created, package_version
    delta_mesh, l_star, t_star   where the dataset has them (t_* the frame where Delta_2 is smallest)
    l_star_fit, t_star_fit       spectra: t_* between the frames and l_* there (spectra.nc's t_star_fit), where the
                                 file has them
    variables         the file's data variables, as a list literal (the ESM variable column)

Missing values are empty cells; integral numbers are written without ".0" (``S`` 553, not 553.0). ``path`` is
relative to the directory holding the catalog, so a results tree can be moved as a whole.

intake-esm (tested with 2025.12.12): ``intake.open_esm_datastore("results/catalog.json")`` groups the assets by
kind and case id (keys ``spectra.D0.116_S553_N32_L3``, one file each). Through the Parquet ``catalog_file`` the
columns keep their types (N, mesh_level, n_vertices int64; Delta, S, chi, delta_mesh, l_star, t_star, l_star_fit,
t_star_fit float64;
empty cells null), so search with numbers: ``N=64``, ``S=553``; a variable by pattern:
``variables=".*'l_star'.*"``. (A catalog written without pyarrow points at the CSV, which intake-esm reads as
text: ``N="64"`` there.)
It opens the relative ``path`` from the current working directory, not from the catalog's: call
``to_dataset_dict()`` with the catalog's directory as working directory (or use :func:`open_sweep`, which resolves
the paths itself).

Case ids are :mod:`vesicle_core.data.case_ids`; a sweep opened as one Dataset is :mod:`vesicle_core.data.sweep`.
"""

from __future__ import annotations

import csv
import json
import math
import os
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ..errors import VesicleError
from ..model.parameters import RUN
from ..model.resolution import DEFAULT_KERNEL  # also the kernel of files written before RunConfig.kernel existed
from .case_ids import parse_case_id

__all__ = [
    "COLUMNS",
    "CatalogError",
    "build_catalog",
    "catalog_row",
    "read_catalog",
    "write_catalog",
]

COLUMNS = ("kind", "case_id", "Delta", "S", "chi", "N", "mesh_family", "mesh_level", "n_vertices", "scheme", "dtype",
           "kernel", "coupling", "tension_space", "kT", "noise_seed", "backend", "tag", "path", "created",
           "package_version", "delta_mesh", "l_star", "t_star", "l_star_fit", "t_star_fit", "variables")
NUMERIC_COLUMNS = ("Delta", "S", "chi", "N", "mesh_level", "n_vertices", "kT", "noise_seed", "delta_mesh", "l_star",
                   "t_star", "l_star_fit", "t_star_fit")
INTEGER_COLUMNS = ("N", "mesh_level", "n_vertices", "noise_seed")
RUN_KINDS = ("trajectory", "spectra", "microscope")

KINDS = ("mesh", "trajectory", "spectra", "microscope", "theory", "fit")
ESMCAT_VERSION = "0.1.0"


class CatalogError(VesicleError, ValueError):
    """A catalog cannot be built or read, or a sweep cannot be stacked (the message says why)."""


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
    if "k_star_section" in ds.variables:
        return "microscope"
    if "Delta_l" in ds.variables:
        return "spectra" if ("face_tension_mean" in ds.variables or "A_p_bar" in ds.variables) else "theory"
    if "node_x" in ds.variables:
        return "trajectory" if "time" in ds.dims else "mesh"
    parts = set(path.parts)
    for kind, folder in (("mesh", "meshes"), ("theory", "theory"), ("fit", "fits")):
        if folder in parts:
            return kind
    raise CatalogError(f"{path}: cannot tell which kind of dataset this is (mesh, trajectory, spectra, microscope, "
                       "theory, fit)")


def _id_from_path(path: Path, kind: str) -> str:
    if kind in RUN_KINDS:
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


def _noise_columns(attrs, kind, parsed) -> dict:
    """kT and noise_seed of a run (the id first, then the attributes); the seed only where the noise is on."""
    if kind not in RUN_KINDS:
        return {"kT": None, "noise_seed": None}
    kT = parsed.get("kT")
    kT = _num_or_nan(_scalar_attr(attrs, "kT") if kT is None else kT)
    kT = 0.0 if not math.isfinite(kT) else kT
    seed = parsed.get("noise_seed")
    seed = _num_or_nan(_scalar_attr(attrs, "noise_seed") if seed is None else seed)
    return {"kT": kT, "noise_seed": int(seed) if kT > 0 and math.isfinite(seed) else None}


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
        delta_mesh = _scalar_attr(attrs, "mesh_delta", "delta_used") if kind in RUN_KINDS else None
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
        if N is None and kind in RUN_KINDS:
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
        noise = _noise_columns(attrs, kind, parsed)
        row.update(
            Delta=_num_or_nan(delta), S=_num_or_nan(S), chi=_num_or_nan(chi),
            N=int(N) if N is not None else None, mesh_family=family if kind != "theory" and kind != "fit" else None,
            mesh_level=int(level) if level is not None and kind not in ("theory", "fit") else None,
            backend=_scalar_attr(attrs, "backend") if kind in RUN_KINDS else None,
            created=_created(attrs, path), package_version=_package_version(attrs),
            delta_mesh=_num_or_nan(delta_mesh), n_vertices=n_vertices, tag=parsed.get("tag"),
            variables=repr(sorted(str(v) for v in ds.data_vars)), **run, **noise,
        )
        if kind in ("spectra", "theory"):
            for name in ("l_star", "t_star", "l_star_fit", "t_star_fit"):
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


def _choices(name: str) -> str:
    """A run parameter's allowed values as the column descriptions list them, from the parameter table."""
    return " | ".join(RUN[name].choices)


def esm_collection(catalog_file: str, description: str | None = None, cid: str = "vesicle-wrinkling") -> dict:
    """ESM-collection (esmcat 0.1.0) description of a catalog table (``catalog_file``: Parquet or CSV)."""
    described = {
        "kind": "dataset kind: mesh | trajectory | spectra | microscope | theory | fit",
        "case_id": "sweep point id (D<Delta>_S<S>_N<N>_L<level>), theory id (D<Delta>_S<S>) or mesh id",
        "Delta": "nominal excess area Delta of the sweep point (1)",
        "S": "flow strength S of the perturbation analysis (1)",
        "chi": "dimensionless extensional rate gamma_dot mu R^3 / kappa (1)",
        "N": "grid nodes per axis",
        "mesh_family": "icosphere | quasiuniform",
        "mesh_level": "icosphere subdivision level",
        "n_vertices": "number of mesh vertices",
        "scheme": f"time-stepping scheme of the run ({_choices('scheme')})",
        "dtype": f"floating-point precision of the run's grid fields ({_choices('dtype')})",
        "kernel": f"regularised delta function of the run ({_choices('kernel')})",
        "coupling": f"fluid-membrane coupling of the run ({_choices('coupling')})",
        "tension_space": f"tension space of the inextensible scheme ({_choices('tension_space')}; triangle for the "
                         "others)",
        "kT": "thermal noise of the run, k_B T / kappa (0: deterministic)",
        "noise_seed": "noise seed of the run (one member of an ensemble), empty when kT = 0",
        "backend": "array backend of the run (numpy | cupy)",
        "tag": "tag of the case (its sweep group), empty when untagged",
        "path": "file location relative to the directory of this catalog",
        "created": "creation time (ISO 8601, UTC) from the dataset's history attribute",
        "package_version": "vesicle_core version that wrote the dataset",
        "delta_mesh": "excess area of the meshed surface (1)",
        "l_star": "characteristic wrinkle mode l_* of eq. (31) at t_*",
        "t_star": "t_* = argmin Delta_2, gamma_dot (t - t0)",
        "l_star_fit": "l_* of eq. (31) at t_star_fit (l_*(t) interpolated between the frames)",
        "t_star_fit": "t_* between the frames: vertex of the parabola through the sampled minimum of Delta_2 and its "
                      "two neighbours, gamma_dot (t - t0)",
        "variables": "data variables of the file, as a list literal ['A_p_bar', 'Delta_l', ...]",
    }
    return {
        "esmcat_version": ESMCAT_VERSION,
        "id": cid,
        "description": description or ("Datasets of a vesicle-wrinkling sweep: meshes, IBM trajectories, spherical-"
                                        "harmonic spectra, virtual microscopy, perturbation-analysis references and "
                                        "power-law fits."),
        "catalog_file": catalog_file,
        "attributes": [{"column_name": c, "vocabulary": "", "description": described[c]} for c in COLUMNS
                       if c != "path"],
        "assets": {"column_name": "path", "format": "netcdf"},
        # intake-esm groups assets by these columns; without aggregation_control it would group by every column and
        # refuse the columns that are empty for some kinds (S of a mesh, ...). kind and case_id are never empty.
        "aggregation_control": {"variable_column_name": "variables", "groupby_attrs": ["kind", "case_id"],
                                "aggregations": []},
    }


def _is_empty(v) -> bool:
    return v is None or (isinstance(v, str) and v == "") or (isinstance(v, float) and math.isnan(v))


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
    (NaN, or None for the integer columns N, mesh_level, n_vertices, noise_seed, when empty), ``variables`` as a
    tuple of names, text columns as strings ("" when empty), and an extra ``abspath`` with the absolute file
    location."""
    return _read_catalog(path)[2]


