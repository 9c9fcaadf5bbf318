"""Which integrator runs a configuration: the scheme's class (:data:`vesicle_core.solver.integrators.SCHEMES`), or a
variant a run parameter selects. Kept apart from both so that a variant module may subclass an integrator."""

from __future__ import annotations


def integrator_class(cfg):
    """The class that runs ``cfg`` (a RunConfig): its scheme's, or the inextensible scheme's midpoint variant
    (``noise_scheme: midpoint``, :mod:`vesicle_core.solver.midpoint`)."""
    from .integrators import SCHEMES

    if cfg.scheme == "inextensible" and cfg.noise_scheme == "midpoint":
        from .midpoint import MidpointInextensible

        return MidpointInextensible
    return SCHEMES[cfg.scheme]
