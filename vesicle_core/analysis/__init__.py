"""Analysis of shapes and runs: the spherical-harmonic decomposition (eqs. 10, 30-32), the spectra of a
trajectory, the perturbation analysis (eqs. 11-12) and the power-law fits (l_* against S, sigma(t) decay).

Imports the model, the data formats and the geometry; never the solver.
"""
