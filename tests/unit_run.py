"""The run parameters of the unit tests: the library defaults they were written against, set explicitly.

The run parameters' defaults are the recommended method (vesicle_core/model/parameters.py: inextensible scheme,
harmonic tension, sharp coupling, 6-point kernel, thermal seed, N = 128), which is what a user gets. The unit tests
check the solver's parts on small grids, each with the discretisation it was written for; :func:`unit_run` builds
their configs on :data:`UNIT_RUN`, the defaults before the change (projection scheme, triangle tension, kernel
coupling, 4-point kernel, mesh-noise seed, N = 32), so that no test's meaning moves when a default does. A test
that is about the defaults uses ``RunConfig()`` itself (tests/model/test_defaults.py).
"""

from vesicle_core.model.run_config import DEFAULTS_BEFORE_RECOMMENDED, RunConfig

UNIT_RUN = dict(DEFAULTS_BEFORE_RECOMMENDED)


def unit_run(**changes) -> RunConfig:
    """RunConfig of UNIT_RUN with the test's own changes."""
    return RunConfig(**{**UNIT_RUN, **changes})
