"""Validation of the solver and of the analysis: single-mode relaxation against linear Stokes theory, the
regularised Stokeslet against Oseen, the resolution ladder and its extrapolation, the PA cut-off study, and the
report that puts the project's numbers next to the paper's.

The one layer that uses both the solver and the analysis (below the figures and the command line).
"""
