"""Data: the analysis Datasets (CF attributes, validated reading), case ids and the catalog of a sweep (CSV, typed
Parquet, ESM collection, ``open_sweep``).

Depends on the model only; the solver and the analysis write and read through it.
"""
