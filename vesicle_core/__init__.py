"""vesicle_core: immersed-boundary simulation and analysis of wrinkling lipid vesicles.

The physics follows the reference paper (equation numbers cited in each module's docstrings).
Internal units (see ``units.py``): lengths in the equivalent radius R, viscosity mu = 1,
bending modulus kappa = 1, so time is measured in tau = mu R^3 / kappa and the
elongational rate of the background flow equals chi = gamma_dot tau.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("vesicle-wrinkling")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+unknown"

#: The public Python API: what a user may import and rely on across versions, as dotted names. Everything else is
#: internal and may change without notice. Declared here as strings, so importing the package stays cheap and the
#: base layer imports nothing above it; docs/reference/api.md documents exactly these (tests/test_public_api.py).
PUBLIC_API = (
    "vesicle_core.geometry.mesh.make_vesicle",
    "vesicle_core.geometry.mesh.Mesh",
    "vesicle_core.geometry.mesh.save",
    "vesicle_core.geometry.mesh.load",
    "vesicle_core.model.run_config.RunConfig",
    "vesicle_core.model.run_config.load_config",
    "vesicle_core.solver.simulate.run",
    "vesicle_core.data.datasets.open_trajectory",
    "vesicle_core.data.datasets.read_dataset",
    "vesicle_core.analysis.spectra.spectra_from_trajectory",
    "vesicle_core.analysis.theory.run_theory",
    "vesicle_core.analysis.stochastic_pa.simulate",
    "vesicle_core.analysis.sweep_fits.sweep_fit_dataset",
    "vesicle_core.data.catalog.write_catalog",
    "vesicle_core.data.catalog.read_catalog",
    "vesicle_core.data.sweep.open_sweep",
    "vesicle_core.errors.VesicleError",
    "vesicle_core.errors.ConfigError",
)

__all__ = ["__version__", "PUBLIC_API"]
