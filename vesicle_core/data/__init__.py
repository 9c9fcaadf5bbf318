"""Data: the analysis Datasets (CF attributes, validated reading, ``datasets``), case ids (``case_ids``), the catalog
of a sweep (CSV, typed Parquet, ESM collection, ``catalog``) and a sweep opened as one Dataset (``sweep``).

Depends on the model only; the solver and the analysis write and read through it.
"""
