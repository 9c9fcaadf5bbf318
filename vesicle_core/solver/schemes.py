"""Which integrator runs a configuration: the scheme's class (:data:`vesicle_core.solver.integrators.SCHEMES`), or a
variant a run parameter selects. Kept apart from both so that a variant module may subclass an integrator."""

from __future__ import annotations


def integrator_class(cfg):
    """The class that runs ``cfg`` (a RunConfig): its scheme's, or the inextensible scheme's midpoint variant
    (``noise_scheme: midpoint``, :mod:`vesicle_core.solver.midpoint`), or its implicitly stabilised variant
    (``stiffness: implicit``, :mod:`vesicle_core.solver.implicit_stiffness`), or its embedded Euler/midpoint pair
    with error control (``step_control: error``, :mod:`vesicle_core.solver.embedded_midpoint`)."""
    from .integrators import SCHEMES

    if cfg.scheme == "inextensible" and cfg.stiffness == "implicit":
        from .implicit_stiffness import StabilisedInextensible

        return StabilisedInextensible
    if cfg.scheme == "inextensible" and cfg.step_control == "error":
        from .embedded_midpoint import EmbeddedMidpoint

        return EmbeddedMidpoint
    if cfg.scheme == "inextensible" and cfg.noise_scheme == "midpoint":
        from .midpoint import MidpointInextensible

        return MidpointInextensible
    return SCHEMES[cfg.scheme]
