"""Physical parameters (Table III, SI) and the dimensionless groups of App. B.

Groups (R: equivalent radius, the radius of the sphere with the vesicle's volume)
    chi    = gamma_dot mu R^3 / kappa              dimensionless extensional rate (Sec. III)
    S      = 16 sqrt(6 pi) chi / (11 sqrt(5 Delta)) flow strength of the perturbation analysis
    Re     = gamma_dot rho R^2 / mu                Reynolds number (App. B)
    Lambda_bar = Lambda R^2 / kappa                dimensionless tension modulus of eq. (A5)
    tau    = mu R^3 / kappa                        bending time scale; gamma_dot t = chi t / tau

Solver units: length R, viscosity mu, bending modulus kappa, so time is in tau and the
background flow is u_inf = chi (x, -y, 0). App. B scales time by 1/gamma_dot instead; the two
differ by the factor chi and every dataset records both times. (With time in 1/gamma_dot the
force term of eq. (B1) carries 1/chi, not chi; working in tau avoids that division and keeps
chi = 0, a vesicle relaxing in still fluid, well defined.)
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from ..errors import ConfigError, check_range

K_BOLTZMANN = 1.380649e-23  # J/K


def S_from_chi(chi: float, delta: float) -> float:
    """Flow strength S = 16 sqrt(6 pi) chi / (11 sqrt(5 Delta)) (Sec. III)."""
    check_range("delta", delta, 0.0, None, lo_open=True)
    return 16.0 * math.sqrt(6.0 * math.pi) * chi / (11.0 * math.sqrt(5.0 * delta))


def chi_from_S(S: float, delta: float) -> float:
    """Inverse of :func:`S_from_chi`."""
    check_range("delta", delta, 0.0, None, lo_open=True)
    return S * 11.0 * math.sqrt(5.0 * delta) / (16.0 * math.sqrt(6.0 * math.pi))


@dataclass(frozen=True)
class Params:
    """SI parameters of one case (defaults: paper Table III, quasi-spherical vesicle, weak flow).

    Attributes are SI: R [m], gamma_dot [1/s], mu [Pa s], kappa [J], rho [kg/m^3], T [K],
    L [m] (periodic box edge), dt [s], Lambda [N/m] (tension modulus of eq. A5), delta [-].
    """

    R: float = 1.671e-5
    gamma_dot: float = 1.0
    delta: float = 0.116
    mu: float = 1.435e-3
    kappa: float = 1.0e-19
    rho: float = 1000.0
    T: float = 293.0
    L: float = 9.0e-5
    dt: float = 1.0e-7
    Lambda: float | None = None

    def __post_init__(self):
        for name in ("R", "mu", "kappa", "L", "dt", "delta"):
            check_range(name, getattr(self, name), 0.0, None, lo_open=True)
        for name in ("gamma_dot", "rho", "T"):
            check_range(name, getattr(self, name), 0.0, None)
        if self.Lambda is not None:
            check_range("Lambda", self.Lambda, 0.0, None, lo_open=True)
        if self.L <= 2.0 * self.R:
            raise ConfigError(f"L must exceed the vesicle diameter 2R = {2 * self.R:g} m, got {self.L:g} m")

    @property
    def tau(self) -> float:
        """Bending time scale mu R^3 / kappa [s]."""
        return self.mu * self.R**3 / self.kappa

    @property
    def chi(self) -> float:
        return self.gamma_dot * self.tau

    @property
    def S(self) -> float:
        return S_from_chi(self.chi, self.delta)

    @property
    def Re(self) -> float:
        return self.gamma_dot * self.rho * self.R**2 / self.mu

    @property
    def rho_bar(self) -> float:
        """Density in solver units (R, mu, kappa): rho kappa / (mu^2 R) = Re / chi when chi > 0."""
        return self.rho * self.kappa / (self.mu**2 * self.R)

    @property
    def L_bar(self) -> float:
        return self.L / self.R

    @property
    def Lambda_bar(self) -> float | None:
        return None if self.Lambda is None else self.Lambda * self.R**2 / self.kappa

    @property
    def dt_tau(self) -> float:
        """Time step in units of tau."""
        return self.dt / self.tau

    @property
    def dt_gamma(self) -> float:
        """Time step in units of 1/gamma_dot (gamma_dot dt)."""
        return self.dt * self.gamma_dot

    @property
    def kT_over_kappa(self) -> float:
        return K_BOLTZMANN * self.T / self.kappa

    def dimensionless(self) -> dict:
        """All groups of App. B as plain floats (what datasets record next to the SI inputs)."""
        return {
            "chi": self.chi,
            "S": self.S,
            "Re": self.Re,
            "rho_bar": self.rho_bar,
            "L_bar": self.L_bar,
            "Lambda_bar": self.Lambda_bar,
            "dt_tau": self.dt_tau,
            "dt_gamma": self.dt_gamma,
            "kT_over_kappa": self.kT_over_kappa,
        }

    def as_dict(self) -> dict:
        return asdict(self)


# --------------------------------------------------------------------------- units in the datasets (CF)
#: Units of the solver that are no UDUNITS units (in UDUNITS "R" is the roentgen and "kappa" and "tau" are
#: unknown). A dataset variable in one of them is written with ``units = "1"`` (CF's dimensionless number) and
#: the scale it is measured in, in this notation, in ``nondimensional_units``; the global attributes of
#: ``SCALE_ATTRS`` define R, kappa, tau and gamma_dot. "same as <variable>" (the scale of another variable of the
#: file) is written the same way.
SOLVER_UNITS = ("R", "R^2", "R^3", "R/tau", "tau", "1/tau", "1/gamma_dot", "kappa", "kappa/R^2", "kappa/R^3")
#: other spellings of the solver units met in the code, written in the files as the form of SOLVER_UNITS
_UNIT_ALIASES = {"R2": "R^2", "R3": "R^3", "kappa R-2": "kappa/R^2", "kappa R-3": "kappa/R^3", "R tau-1": "R/tau"}

#: Global attributes that state the scales of ``nondimensional_units`` (every dataset carries them).
SCALE_ATTRS = {
    "units_convention": ("nondimensional: a variable with units '1' and an attribute nondimensional_units = 'X' "
                         "holds a number in units of X (R, kappa, tau, gamma_dot below); units '1' alone: a pure "
                         "number"),
    "length_scale": "R: radius of the sphere with the vesicle's volume, V = 4/3 pi R^3",
    "energy_scale": "kappa: bending modulus of the membrane (tension in kappa/R^2)",
    "viscosity_scale": "mu: viscosity of the fluid, the same inside and outside",
    "time_scale": "tau = mu R^3 / kappa; the flow rate is gamma_dot = chi / tau, so 1/gamma_dot = tau / chi",
}


def cf_unit_attrs(attrs: dict) -> dict:
    """``attrs`` of one variable with its ``units`` made a CF unit: a solver unit (``SOLVER_UNITS``, or "same as
    <variable>") becomes units "1" with ``nondimensional_units`` naming the scale; anything else is returned
    unchanged (so the call is idempotent)."""
    u = attrs.get("units")
    u = _UNIT_ALIASES.get(u, u) if isinstance(u, str) else u
    if not isinstance(u, str) or not (u in SOLVER_UNITS or u.startswith("same as ")):
        return attrs
    out = dict(attrs)
    out["units"] = "1"
    out["nondimensional_units"] = u
    return out
