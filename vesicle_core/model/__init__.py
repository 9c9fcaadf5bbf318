"""The model: physical parameters and units (Table III, App. B), the background flow (Sec. II B), every run and
mesh parameter defined once, and the run configuration built from them.

Nothing here imports the solver or the analysis; both build on it.
"""
