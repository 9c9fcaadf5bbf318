"""A sweep opened as one xarray Dataset, and catalog rows selected by column values.

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
``n_vertices``, ``mesh_family``, ``scheme``, ``dtype``, ``kernel``, ``coupling``, ``tension_space``, ``kT``,
``noise_seed``, ``tag``.

Ensembles: when the selected runs hold more than one ``noise_seed`` (thermal noise, one case per seed), the seed
is a third dimension, ``noise_seed``, and l_* is a distribution: ``sw.l_star.mean("noise_seed")``,
``sw.l_star.std("noise_seed", ddof=1)``. Runs of different kT at one point are told apart by selecting ``kT=``;
deterministic and noisy runs cannot share one stack (select ``kT=0`` or ``kT=0.0405``).
If two catalog rows share (Delta, S) (e.g. two grids or two meshes), select by any catalog column:
``open_sweep("results/catalog.csv", N=64, n_vertices=642)``, ``scheme="projection"``, ``tag="coarse"``. Numeric
columns compare as numbers (``n_vertices="642"`` selects 642; floats to 1e-9 relative), a list selects any of its
values, ``None`` or ``""`` selects empty cells, and ``variables="l_star"`` the files holding that variable.
"""

from __future__ import annotations

import math

import numpy as np

from .catalog import (
    COLUMNS,
    INTEGER_COLUMNS,
    NUMERIC_COLUMNS,
    CatalogError,
    _catalog_csv,
    _is_empty,
    _num_or_nan,
    _read_catalog,
)

__all__ = ["open_sweep", "select_rows"]


# --------------------------------------------------------------------------- selecting rows
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
                        "tension_space", "kT", "backend", "tag", "chi")


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


def _seed_dimension(rows, kind) -> bool:
    """True when the rows are an ensemble (several noise seeds); refuses a mix of deterministic and noisy runs."""
    seeds = {None if _is_empty(r.get("noise_seed")) else int(float(r["noise_seed"])) for r in rows}
    if len(seeds) <= 1:
        return False
    if None in seeds:
        kTs = sorted({_num_or_nan(r.get("kT")) for r in rows})
        raise CatalogError(f"the {kind} datasets mix deterministic and noisy runs (kT = "
                           f"{', '.join(f'{k:g}' for k in kTs)}); select one: kT=0 or kT=<value>")
    return True


def open_sweep(path, kind: str = "spectra", time=None, **where):
    """All datasets of one kind in a catalog as one xarray Dataset on the sweep dimensions (Delta, S), and
    ``noise_seed`` for an ensemble (module docstring).

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
    by_seed = _seed_dimension(rows, kind)
    keys = {}
    for r in rows:
        k = (r["Delta"], r["S"], r.get("noise_seed")) if by_seed else (r["Delta"], r["S"])
        if k in keys:
            other = keys[k]
            differ = [c for c in _SELECT_HINT_COLUMNS if c in columns and not _same(other[c], r[c])]
            hint = (f"select one with a column where they differ: {', '.join(f'{c}=...' for c in differ)} "
                    "(or case_id=...)") if differ else "select one with case_id=..."
            at = f"Delta={k[0]:g}, S={k[1]:g}" + (f", noise_seed={k[2]}" if by_seed else "")
            raise CatalogError(f"two {kind} datasets at {at} ({other['case_id']} and "
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
        for c in (*INTEGER_COLUMNS, "kT"):
            if c in r and not (by_seed and c == "noise_seed"):
                meta[c] = float(r[c]) if not _is_empty(r[c]) else math.nan
        for c in ("mesh_family", "scheme", "dtype", "kernel", "coupling", "tension_space", "tag"):
            meta[c] = str(r[c] or "")
        for k, v in meta.items():
            red[k] = xr.DataArray(v)
        dims = {"Delta": [r["Delta"]], "S": [r["S"]]}
        if by_seed:
            dims["noise_seed"] = [int(r["noise_seed"])]
        red = red.expand_dims(dims)
        parts.append(red)
    out = xr.merge(parts, join="outer", compat="no_conflicts", combine_attrs="drop")
    out = out.sortby(["Delta", "S", "noise_seed"] if by_seed else ["Delta", "S"])
    if by_seed:
        out["noise_seed"].attrs.update(long_name="noise seed of the run (ensemble member)")
    out["Delta"].attrs.update(units="1", long_name="excess area Delta (nominal)")
    out["S"].attrs.update(units="1", long_name="flow strength S")
    if "time" in out.coords:
        out["time"].attrs.update(units="1/gamma_dot", long_name="gamma_dot (t - t0), common grid (interpolated)")
    out.attrs.update(title=f"vesicle-wrinkling sweep: {kind} stacked along (Delta, S)",
                     catalog=str(_catalog_csv(path)), kind=kind,
                     time_note="time series linearly interpolated onto a common grid; NaN outside a run's range")
    return out
