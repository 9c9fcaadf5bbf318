"""The immersed boundary solver (Sec. IV): array backend, kernels (eqs. 26-27), spreading and interpolation, the
periodic Stokes solve (eqs. 17-23, 29), membrane forces (App. A), the mobility, the tension solves, the time
integrators, thermal noise, and the time loop with its trajectory and checkpoints.

Imports the model, the data formats and the geometry; never the analysis.
"""
