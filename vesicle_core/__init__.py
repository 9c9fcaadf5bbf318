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

__all__ = ["__version__"]
