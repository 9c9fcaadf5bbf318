"""The configuration of one IBM run: :class:`RunConfig`, the default tension modulus and the YAML loader.

``RunConfig`` is a frozen dataclass with one field per entry of :data:`vesicle_core.model.parameters.RUN_PARAMETERS`,
in the table's order and with its defaults (ranges, choices and help live in that one table, which also writes the
workflow's schema; tests/model/test_run_config.py fails when the fields and the table differ). ``__post_init__``
checks every field through the table and adds the rules that tie the fields together; the derived quantities (h,
Lambda_eff, rho_bar, the time scale) are properties.

Units are the solver's: lengths in R, mu = kappa = 1, time in tau = mu R^3/kappa; the background rate is chi.
All durations are in gamma_dot t (= chi t/tau) when chi > 0, in tau when chi = 0.
"""

from dataclasses import asdict, dataclass, fields

from ..errors import ConfigError
from .parameters import RUN_PARAMETERS, SHARP_FLOOR

#: the defaults that changed when the run parameters' defaults became the recommended method (version 0.1.0 kept
#: these): a trajectory's attributes lack a key only when it was written before that key existed, and it then ran
#: with the key's default of the time, not today's (RunConfig.from_attrs)
DEFAULTS_BEFORE_RECOMMENDED = {"N": 32, "kernel": "peskin4", "coupling": "kernel", "scheme": "projection", "t_end": 1.5,
                               "tension_space": "triangle", "mesh_ale": "none", "seed_spectrum": "mesh"}


#: the run parameters of the paper's own method (Secs. II-IV), where they differ from the defaults: the explicit
#: scheme (the area penalty alone), the kernel coupling with Peskin's 4-point kernel (eqs. 16, 27, 28), the
#: barycentric vertex area, and no seed but the mesh's own noise (the paper's IBM has no thermal noise). It needs a
#: mesh of edge ~2h (the paper: 26 070 vertices at 512^3; 2562 at N = 128). config/paper_method.yaml runs it.
PAPER_METHOD = {
    "scheme": "explicit",
    "coupling": "kernel",
    "kernel": "peskin4",
    "area_model": "barycentric",
    "seed_spectrum": "mesh",
    "tension_space": "triangle",
    "mesh_ale": "none",
}


@dataclass(frozen=True)
class RunConfig:
    """Parameters of one IBM run, in solver units (see module docstring): the fields, defaults and ranges of
    :data:`vesicle_core.model.parameters.RUN_PARAMETERS`, checked on creation, plus the rules that tie them together."""

    chi: float = 67.0
    N: int = 128
    L: float = 5.0
    Re: float = 0.0
    Lambda: float | None = None
    K_volume: float = 1.0e7
    K_area: float = 0.0
    area_model: str = "voronoi"
    kernel: str = "bao6"
    coupling: str = "sharp"
    sharp_floor: float = SHARP_FLOOR
    scheme: str = "inextensible"
    projection_refresh: int = 10
    stretch: float = 1.0
    stationary_tol: float = 0.0
    t_end: float = 1.0
    dt: float | str = "power"  # a fixed step in tau, or "power" / "formula"
    dt_safety: float = 0.8
    output_every: float = 0.02
    checkpoint_every: int = 2000
    max_drift: float = 0.05
    backend: str = "numpy"
    dtype: str = "float64"
    fft_workers: int = 1
    cg_tol: float = 1.0e-5
    cg_maxiter: int = 200
    cg_precond: str = "auto"
    tension_space: str = "harmonic"
    tension_l_max: int | None = None
    mesh_ale: str = "quality"
    stiffness: str = "explicit"
    stiffness_l: float | None = None
    stiffness_tension: bool = True
    tension_fixed: float | None = None
    dt_growth: float = 0.1
    dt_strain: float = 2.0e-3
    seed_spectrum: str = "thermal"
    seed_scale: float = 1.0
    seed: int = 0
    kT: float = 0.0
    noise_seed: int = 0
    noise_step: float = 0.04
    noise_scheme: str = "lm"
    noise_drift_every: int = 1
    step_control: str = "limits"
    step_tol: float = 0.025
    store_velocity: bool = False

    def __post_init__(self):
        for p in RUN_PARAMETERS:  # a frozen dataclass: store the normalised value (e.g. 128.0 -> 128)
            object.__setattr__(self, p.name, p.check(getattr(self, p.name)))
        if self.scheme == "inextensible" and self.Re > 0:
            raise ConfigError(f"scheme 'inextensible' solves steady Stokes (Re = 0); got Re = {self.Re:g}")
        if self.tension_space == "harmonic" and self.cg_precond == "local":
            raise ConfigError("tension_space 'harmonic' has its own preconditioner (the measured area rate per l); "
                              "cg_precond 'local' applies to tension_space 'triangle' only")
        if self.tension_space != "harmonic" and self.cg_precond == "secant":
            raise ConfigError("cg_precond 'secant' learns the harmonic tension's operator; it applies to "
                              f"tension_space 'harmonic' only, got '{self.tension_space}'")
        if self.mesh_ale != "none" and self.tension_space != "harmonic":
            raise ConfigError(f"mesh_ale '{self.mesh_ale}' applies to tension_space 'harmonic' only (the triangle "
                              "tension holds every triangle's area itself); set mesh_ale: none")
        if self.tension_fixed is not None and (self.scheme != "inextensible" or self.tension_space != "harmonic"):
            raise ConfigError(f"tension_fixed = {self.tension_fixed:g} needs scheme 'inextensible' with tension_space "
                              f"'harmonic' (it fixes that space's l = 0 coefficient); got scheme '{self.scheme}', "
                              f"tension_space '{self.tension_space}' (or set tension_fixed: null)")
        if self.chi == 0 and self.stretch > 0:
            raise ConfigError("stretch must be 0 when chi = 0 (no flow to stretch in); t_end is then in tau")
        if self.kT > 0 and self.scheme != "inextensible":
            raise ConfigError(f"kT > 0 needs scheme 'inextensible' (the noise enters its tension solve); got scheme "
                              f"'{self.scheme}' (or set kT = 0)")
        if self.noise_scheme == "midpoint" and self.scheme != "inextensible":
            raise ConfigError(f"noise_scheme 'midpoint' is a variant of scheme 'inextensible' (two tension solves per "
                              f"step); got scheme '{self.scheme}'")
        if self.stiffness == "implicit" and (self.scheme != "inextensible" or self.kT > 0
                                             or self.noise_scheme == "midpoint"):
            raise ConfigError(f"stiffness 'implicit' is a variant of scheme 'inextensible' without noise and without "
                              f"noise_scheme 'midpoint'; got scheme '{self.scheme}', kT = {self.kT:g}, noise_scheme "
                              f"'{self.noise_scheme}' (or set stiffness: explicit)")
        if self.step_control == "error" and (self.scheme != "inextensible" or self.kT > 0
                                             or self.stiffness != "explicit" or isinstance(self.dt, (int, float))):
            raise ConfigError(f"step_control 'error' is a variant of scheme 'inextensible' with an adaptive dt, "
                              f"without noise and with stiffness 'explicit'; got scheme '{self.scheme}', "
                              f"dt = {self.dt!r}, kT = {self.kT:g}, stiffness '{self.stiffness}' "
                              "(or set step_control: limits)")
        if self.kT > 0 and self.seed_spectrum != "mesh":
            raise ConfigError(f"kT = {self.kT:g} with seed_spectrum '{self.seed_spectrum}': the noise keeps the "
                              "membrane thermal throughout, and the PA's thermal seed at the reversal would add a "
                              "second thermal spectrum on top; set seed_spectrum: mesh for noisy runs")
        if self.seed_spectrum != "mesh" and self.stationary_tol > 0:
            raise ConfigError("seed_spectrum 'thermal' needs a fixed stretch (stationary_tol = 0): the seed goes on "
                              "the shape before the frame at the reversal; set stationary_tol: 0 or "
                              "seed_spectrum: mesh")

    @property
    def tension_preconditioner(self) -> str:
        """cg_precond resolved: auto is secant for a noisy run with the harmonic tension, compliance otherwise."""
        if self.cg_precond != "auto":
            return self.cg_precond
        return "secant" if self.kT > 0 and self.tension_space == "harmonic" else "compliance"

    @property
    def h(self) -> float:
        return self.L / self.N

    @property
    def Lambda_eff(self) -> float:
        return default_lambda(self.chi, self.scheme) if self.Lambda is None else float(self.Lambda)

    @property
    def rho_bar(self) -> float:
        """Density in solver units: Re / chi (App. B with time in tau)."""
        return self.Re / self.chi if self.chi > 0 else 0.0

    def time_scale(self) -> float:
        """tau per unit of the configured durations: 1/chi, or 1 when chi = 0."""
        return 1.0 / self.chi if self.chi > 0 else 1.0

    @classmethod
    def from_dict(cls, d: dict) -> "RunConfig":
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ConfigError(f"unknown run parameter(s) {unknown}; allowed: {sorted(names)}")
        return cls(**d)

    @classmethod
    def from_attrs(cls, attrs: dict) -> "RunConfig":
        """The run parameters of a trajectory's attributes (the inverse of :meth:`as_attrs` after a netCDF round
        trip: None stored as "default", booleans as "True"/"False", numbers as NumPy scalars); other keys are
        ignored. A key the attributes lack takes its default from before the recommended method became the default
        (:data:`DEFAULTS_BEFORE_RECOMMENDED`): every trajectory written since records every key."""
        names = {f.name for f in fields(cls)}

        def value(v):
            if isinstance(v, str):
                return {"default": None, "True": True, "False": False}.get(v, v)
            return v.item() if hasattr(v, "item") else v

        return cls.from_dict({**DEFAULTS_BEFORE_RECOMMENDED, **{k: value(v) for k, v in attrs.items() if k in names}})

    def as_attrs(self) -> dict:
        out = {}
        for k, v in asdict(self).items():
            out[k] = "default" if v is None else v
        out["Lambda_eff"] = self.Lambda_eff
        out["h"] = self.h
        return out


def legacy_config(**changes) -> RunConfig:
    """RunConfig of the defaults before they became the recommended method (DEFAULTS_BEFORE_RECOMMENDED: projection
    scheme, triangle tension, kernel coupling, 4-point kernel, mesh-noise seed, N = 32), with ``changes``: what the
    studies in benchmarks/ and the measurement history in docs/history/ ran when they left a key unset."""
    return RunConfig(**{**DEFAULTS_BEFORE_RECOMMENDED, **changes})


def default_lambda(chi: float, scheme: str = "explicit") -> float:
    """Default tension modulus of (A5) [kappa/R^2].

    explicit:   the penalty alone holds the area, so the area strain sigma/Lambda must stay below ~0.2%.
                The stretched steady state has sigma ~ 26 chi kappa/R^2 (1770 measured at chi = 67), so
                Lambda = 1.5e4 chi with a floor of 1e5 (1e6 at chi = 67, 4e6 at chi = 268), strain ~0.18%.
    projection: a global multiplier carries the mean tension and holds the total area exactly; the local
                penalty only has to resist tension *differences* along the membrane, so it is 10x softer
                (1.5e3 chi, floor 1e4), which makes the explicit step limit 40 h/Lambda 10x larger.
    inextensible: Lambda is the area-stretch modulus of the constraint (strain sigma/Lambda), treated
                implicitly, so it costs no time step: 5e4 chi (floor 1e6) keeps the strain near 5e-4.
    """
    if scheme == "inextensible":
        return max(1.0e6, 5.0e4 * chi)
    if scheme == "projection":
        return max(1.0e4, 1.5e3 * chi)
    return max(1.0e5, 1.5e4 * chi)


def load_config(path) -> RunConfig:
    """A RunConfig from a YAML file holding a mapping of run parameters (``vesicle run --params``).

    Unknown keys and values out of range raise ConfigError naming the file, the key and the allowed values;
    duplicate keys are refused rather than silently overwritten.
    """
    import yaml

    from ..io import safe_load_unique

    try:
        with open(path) as fh:
            d = safe_load_unique(fh) or {}
    except FileNotFoundError:
        raise ConfigError(f"parameter file {path} does not exist") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"parameter file {path} is not valid YAML: {exc}") from None
    if not isinstance(d, dict):
        raise ConfigError(f"parameter file {path} must hold a mapping of run parameters")
    try:
        return RunConfig.from_dict(d)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
