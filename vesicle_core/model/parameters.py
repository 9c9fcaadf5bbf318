"""Every run and mesh parameter, defined once: name, default, unit, allowed values and meaning.

``RunConfig`` (run_config.py) has one field per entry of :data:`RUN_PARAMETERS` and checks its values with it; the
workflow takes its defaults and its list of keys from here. The config schema's ``run``/``mesh`` sections and the
parameter tables of config/README.md are generated from these tables by :mod:`vesicle_core.model.parameter_docs`
(``python -m vesicle_core.model.parameter_docs --write``), and tests/model/test_parameters.py fails when any of them
drifts. ``vesicle params`` prints the tables with defaults.
Cross-parameter rules (N even, no inextensible scheme at Re > 0, ...) live in ``RunConfig.__post_init__``.

The defaults are the recommended method, the default job's (config/config.yaml; tests/model/test_defaults.py holds
the two together), so `vesicle mesh` then `vesicle run` without options run it; the paper's: run_config.PAPER_METHOD.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError, check_range
from .resolution import KERNELS


def _yaml_number_hint(text) -> str:
    """Why a number may have arrived as text: YAML 1.1 (PyYAML) reads 1.0e8 as a string, 1.0e+8 as a number."""
    try:
        float(text)
    except ValueError:
        return ""
    return (" (a number given as text: YAML reads an exponent without a sign, 1.0e8, as a string; write 1.0e+8 "
            "or 100000000.0)")


@dataclass(frozen=True)
class Parameter:
    """One parameter. kind: "float", "int", "str" (with choices), "bool"; ``nullable`` allows None ("null")."""

    name: str
    default: object
    kind: str
    help: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple = ()
    nullable: bool = False
    also: tuple = ()  # extra string values a number parameter accepts (dt: "power", "formula")
    multiple_of: int | None = None
    workflow: bool = True  # set per case by the workflow's config (chi comes from the sweep instead)

    def check(self, value):
        """The value if allowed, else ConfigError naming the parameter and its allowed values."""
        if value is None:
            if self.nullable:
                return None
            raise ConfigError(f"{self.name} must be set ({self.allowed()}), got None")
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise ConfigError(f"{self.name} must be true or false, got {value!r}")
            return value
        if self.kind == "str":
            if value not in self.choices:
                raise ConfigError(f"{self.name} must be one of {self.choices}, got {value!r}")
            return value
        if isinstance(value, str):
            if value in self.also:
                return value
            raise ConfigError(f"{self.name} must be {self.allowed()}, got {value!r}{_yaml_number_hint(value)}")
        v = check_range(self.name, value, self.lo, self.hi, lo_open=self.lo_open, integer=self.kind == "int")
        if self.multiple_of and v % self.multiple_of:
            raise ConfigError(f"{self.name} must be a multiple of {self.multiple_of}, got {v}")
        return v

    def allowed(self) -> str:
        """The allowed values in words, as the docs show them."""
        if self.kind == "bool":
            text = "true | false"
        elif self.kind == "str":
            text = " | ".join(self.choices)
        else:
            left = "(" if self.lo_open else "["
            lo = "-inf" if self.lo is None else _num(self.lo)
            hi = "inf)" if self.hi is None else f"{_num(self.hi)}]"
            text = ("integer " if self.kind == "int" else "") + f"{left}{lo}, {hi}"
            if self.multiple_of:
                text += f", multiple of {self.multiple_of}"
            if self.also:
                text = " | ".join(f'"{a}"' for a in self.also) + " | " + text
        return text + (" | null" if self.nullable else "")

    def json_schema(self) -> dict:
        """The JSON-schema fragment of this parameter (no default: defaults come from this table)."""
        if self.kind == "bool":
            out = {"type": "boolean"}
        elif self.kind == "str":
            out = {"type": "string", "enum": list(self.choices)}
        else:
            out = {"type": "integer" if self.kind == "int" else "number"}
            if self.lo is not None:
                out["exclusiveMinimum" if self.lo_open else "minimum"] = self.lo
            if self.hi is not None:
                out["maximum"] = self.hi
            if self.multiple_of:
                out["multipleOf"] = self.multiple_of
            if self.also:
                out = {"oneOf": [{"type": "string", "enum": list(self.also)}, out]}
        if self.nullable:
            out = {"oneOf": [{"type": "null"}, out]}
        desc = self.help + (f" [{self.unit}]" if self.unit else "")
        return {**out, "description": desc}


def _num(x) -> str:
    if isinstance(x, int) or (float(x).is_integer() and abs(x) < 1e5):
        return str(int(x))
    return f"{x:g}"


#: the time integrators, in the order the docs list them: the one list of scheme names (RunConfig checks a run's
#: scheme against it, solver/integrators.py registers one class per name and fails to import if they differ)
SCHEMES = ("explicit", "projection", "inextensible")
# A checkpoint is also written once this much wall time has passed since the last one, whatever checkpoint_every
# says: an adaptive 256^3 run takes ~400 steps in ~1 h, so the step count alone would leave it without any
# checkpoint, and a job killed without a signal (node failure, SIGKILL) would lose all of it. A 10242-vertex
# checkpoint took 4.8 ms to write (median of 5, two 256^3 runs on the machine).
CHECKPOINT_WALL_S = 600.0
_KERNELS = tuple(KERNELS)
# the sharp coupling's floor, chosen from the resolution table alone (docs/explanation/resolution.md, "Sharpened
# coupling")
SHARP_FLOOR = 0.01

#: parameters of one IBM run (``vesicle run``, ``RunConfig``), in solver units (R, kappa, tau = mu R^3 / kappa)
RUN_PARAMETERS: tuple[Parameter, ...] = (
    Parameter(
        "chi", 67.0, "float", "dimensionless extensional rate gamma_dot mu R^3 / kappa", "1", 0.0, 1e7, workflow=False
    ),
    Parameter("N", 128, "int", "grid nodes per axis", "", 8, 4096, multiple_of=2),
    Parameter(
        "L",
        5.0,
        "float",
        "periodic box edge (Table III: 90 um / R = 5.386 at R = 16.71 um, 5.0 at R = 18 um)",
        "R",
        2.0,
        1000.0,
        lo_open=True,
    ),
    Parameter(
        "Re",
        0.0,
        "float",
        "Reynolds number gamma_dot rho R^2 / mu; 0 = steady Stokes (Table III gives ~2e-4)",
        "",
        0.0,
        10.0,
    ),
    Parameter(
        "Lambda",
        None,
        "float",
        "tension modulus of eq. (A5); null = the default for chi and scheme "
        "(vesicle_core.model.run_config.default_lambda: 1.5e4 chi explicit, 1.5e3 chi projection; inextensible: "
        "the area-stretch modulus of the constraint, 5e4 chi, floor 1e6)",
        "kappa/R^2",
        0.0,
        1e12,
        nullable=True,
    ),
    Parameter("K_volume", 1.0e7, "float", "global volume penalty; holds V without costing dt", "kappa/R^3", 0.0, 1e12),
    Parameter("K_area", 0.0, "float", "global area penalty", "kappa/R^2", 0.0, 1e12),
    Parameter(
        "area_model",
        "voronoi",
        "str",
        "vertex area in the bending energy (barycentric: the paper's)",
        choices=("voronoi", "barycentric"),
    ),
    Parameter(
        "kernel",
        "bao6",
        "str",
        "regularised delta: Peskin's 4-point (eq. 27), Roma-Peskin-Berger 3-point, "
        "Bao-Kaye-Peskin 6-point (kernels.py)",
        choices=_KERNELS,
    ),
    Parameter(
        "coupling",
        "sharp",
        "str",
        "fluid-membrane coupling. kernel: spread and interpolate with the kernel (eqs. 16, 28; the paper's); "
        "sharp: also divide the spread force's spectrum by the kernel's squared Fourier transform, floored at "
        "sharp_floor (window deconvolution: resolves ~2x higher l per grid node; needs a mesh edge of ~h, "
        "docs/history/solver.md)",
        choices=("kernel", "sharp"),
    ),
    Parameter(
        "sharp_floor",
        SHARP_FLOOR,
        "float",
        "sharp coupling: floor on the kernel's squared Fourier transform (the largest amplification is "
        "1/sharp_floor); chosen by the resolution table (docs/history/solver.md)",
        "",
        1e-4,
        1.0,
    ),
    Parameter(
        "scheme",
        "inextensible",
        "str",
        "time integrator (integrators.py). explicit: the paper's area penalty alone; "
        "projection: a global tension multiplier holds the area exactly (10x larger steps); inextensible: a "
        "tension solved each step from the local area constraint (per triangle or in spherical harmonics: "
        "tension_space), adaptive steps (docs/explanation/method.md)",
        choices=SCHEMES,
    ),
    Parameter(
        "projection_refresh",
        10,
        "int",
        "steps between recomputations of cached mobility data (projection, inextensible)",
        "",
        1,
        10000,
    ),
    Parameter("stretch", 1.0, "float", "longest forward-flow phase before the reversal", "gamma_dot t", 0.0, 1e4),
    Parameter(
        "stationary_tol",
        0.0,
        "float",
        "reverse early once the relative shape change per gamma_dot t is below this (0 = never)",
        "",
        0.0,
        1.0,
    ),
    Parameter("t_end", 1.0, "float", "duration after the reversal", "gamma_dot t", 0.0, 1e4),
    Parameter(
        "dt",
        "power",
        "float",
        "time step: power (the stiffest mode of the linearised operator, by Arnoldi iteration), the stability "
        "formula (formula_dt: area penalty 40 h/Lambda, bending 13-20 h^3), or fixed; the "
        "inextensible scheme re-estimates it every step",
        "tau",
        0.0,
        1.0,
        lo_open=True,
        also=("power", "formula"),
    ),
    Parameter("dt_safety", 0.8, "float", "fraction of the stability limit used as the step. The limit is measured "
              "at the initial shape; a vesicle that deforms strongly (Delta ~ 1) stiffens as it stretches and needs "
              "~0.4 with the explicit and projection schemes. An unstable run stops with exit status 3 and "
              "failure.nc", "", 0.0, 1.0, lo_open=True),
    Parameter(
        "output_every",
        0.02,
        "float",
        "interval between stored frames (the time resolution of every curve)",
        "gamma_dot t",
        0.0,
        1e4,
        lo_open=True,
    ),
    Parameter(
        "checkpoint_every",
        2000,
        "int",
        f"steps between checkpoints; one is also written after every {CHECKPOINT_WALL_S / 60:g} min of wall time "
        "and on SIGINT/SIGTERM (a restarted job resumes from the last one)",
        "",
        1,
        None,
    ),
    Parameter(
        "max_drift",
        0.05,
        "float",
        "relative area or volume drift that stops a run as unstable",
        "",
        0.0,
        1.0,
        lo_open=True,
    ),
    Parameter(
        "backend",
        "numpy",
        "str",
        "array module; cupy needs a GPU (and resources.simulate.gpu: 1)",
        choices=("numpy", "cupy", "auto"),
    ),
    Parameter(
        "dtype",
        "float64",
        "str",
        "precision of grid fields and FFTs (positions and forces stay float64)",
        choices=("float64", "float32"),
    ),
    Parameter("fft_workers", 1, "int", "CPU FFT threads; also the workflow job's threads", "", 1, 256),
    Parameter(
        "cg_tol",
        1.0e-5,
        "float",
        "inextensible: CG tolerance, rms area strain of the residual; the next "
        "step corrects it, so it does not accumulate (docs/history/solver.md)",
        "",
        0.0,
        1e-2,
        lo_open=True,
    ),
    Parameter("cg_maxiter", 200, "int", "inextensible: CG iterations before the run stops (NumericalInstability)", "",
              1, 100000),
    Parameter(
        "cg_precond",
        "auto",
        "str",
        "inextensible: CG preconditioner. local adds the IBM's measured "
        "near-field mobility (LU-factorised every projection_refresh steps); it needs a mesh edge of ~2h and "
        "pays up to 128^3 (there 0.86x the projection scheme's time, docs/history/solver.md); at 256^3 it halves the "
        "elongated vesicle's iterations (Delta ~ 1: 2.1x faster through the late stretch) but slows the "
        "quasi-spherical one (no fewer warm-step iterations): compliance there. secant (tension_space harmonic): "
        "BFGS updates of the measured diagonal from every CG product (tension_secant.py; 1.8-3.6x fewer CG "
        "iterations with noise). auto: secant for kT > 0 with the harmonic tension, compliance otherwise",
        choices=("auto", "compliance", "local", "secant"),
    ),
    Parameter(
        "tension_space",
        "harmonic",
        "str",
        "inextensible: the tension's space. triangle: one tension per triangle, every triangle's area held "
        "(near-null checkerboard modes); harmonic: a Galerkin tension in real spherical harmonics up to "
        "tension_l_max on the reference mesh's sphere coordinates, the projection of the area change on that "
        "space held, CG preconditioned by the measured area rate per l (docs/history/solver.md, A harmonic tension)",
        choices=("triangle", "harmonic"),
    ),
    Parameter(
        "tension_l_max",
        None,
        "int",
        "tension_space harmonic: highest l of the tension; null = half the mesh's resolvable l "
        "(pi R / mean edge / 2: 10 at 642 vertices, 20 at 2562, 40 at 10242)",
        "",
        0,
        200,
        nullable=True,
    ),
    Parameter(
        "mesh_ale",
        "quality",
        "str",
        "tension_space harmonic: area adds a tangential vertex velocity (least squares, no Stokes solve) that holds "
        "the triangle areas the harmonic tension leaves free, so the mesh keeps carrying the strain; shape also "
        "keeps the triangles' angles (a shear) and carries the lipid area the mesh moves; quality adds shape's angle "
        "rows only on triangles below 90% of their reference quality (full weight below 60%)",
        choices=("none", "area", "shape", "quality"),
    ),
    Parameter("stiffness", "explicit", "str", "inextensible: explicit bending, or implicit (alpha (-L)^2 + beta "
              "(-L) on the normals solved implicitly, the step the measured stability limit of the step taken; "
              "docs/explanation/implicit-stiffness.md)",
              choices=("explicit", "implicit")),
    Parameter("stiffness_l", None, "float", "stiffness implicit: l where the stabilisation reaches half the start's "
              "stiffest rate; null = pi R / h / 2", "", 2.0, 1000.0, nullable=True),
    Parameter("stiffness_tension", True, "bool", "stiffness implicit: also stabilise the tension's stiffness (beta "
              "(-L) on the normals, sized from the largest positive tension) and drop the tension formula's limit for "
              "the measured one; false: bending only (alpha (-L)^2), the tension formula's limit kept"),
    Parameter("tension_fixed", None, "float", "tension_space harmonic: null = the total area is held; a number = the "
              "uniform (l = 0) tension is fixed at it and the total area is free (a fixed-tension ensemble for "
              "equilibrium checks); l >= 1 still holds the local area", "kappa/R^2", 0.0, 1e7, nullable=True),
    Parameter(
        "dt_growth",
        0.1,
        "float",
        "inextensible, adaptive dt: e-folds of the fastest wrinkle mode the grid "
        "resolves per step, and dt_growth/10 strain units of the background flow per step",
        "",
        0.0,
        1.0,
        lo_open=True,
    ),
    Parameter(
        "dt_strain",
        2.0e-3,
        "float",
        "inextensible, adaptive dt, no thermal noise: the largest strain of the held area (the triangle's, or its "
        "projection on the harmonic space) that one step may add beyond first order in its displacement, which the "
        "linearised constraint cannot see; it peaks while the wrinkles flatten out (dt scales as its inverse "
        "square root; 1 leaves the step to the other limits)",
        "",
        0.0,
        1.0,
        lo_open=True,
    ),
    Parameter(
        "seed_spectrum",
        "thermal",
        "str",
        "wrinkle seed at the reversal: mesh noise only, or the PA's thermal spectrum (seeding.py)",
        choices=("mesh", "thermal"),
    ),
    Parameter("seed_scale", 1.0, "float", "thermal seed: factor on k_B T (the variance of every mode)", "", 0.0, 1e6),
    Parameter("seed", 0, "int", "thermal seed: random draw (the PA's seed)", "", 0, 2**31 - 1),
    Parameter(
        "kT",
        0.0,
        "float",
        "thermal noise on throughout the run: k_B T / kappa of the fluctuating Stokes velocity (0: deterministic; "
        "0.0405 at 293 K and kappa = 1e-19 J); inextensible scheme only (fluctuations.py)",
        "kappa",
        0.0,
        1e3,
    ),
    Parameter(
        "noise_seed",
        0,
        "int",
        "thermal noise: key of its counter-based generator (the numbers of a step depend on the key and the step "
        "only: the same on NumPy and CuPy and across a resume)",
        "",
        0,
        2**31 - 1,
    ),
    Parameter(
        "noise_step",
        0.04,
        "float",
        "thermal noise, adaptive dt: the largest rms noise displacement per step and component, in grid spacings h "
        "(dt <= (noise_step h)^2 / (2 kT m_self), m_self the markers' self-mobility; runs stop from ~0.06 on, "
        "studies/noise_step_limit.py; 1 leaves the step to the other limits)",
        "h",
        0.0,
        1.0,
        lo_open=True,
    ),
    Parameter("noise_scheme", "lm", "str", "thermal noise: euler (each step its own draw; spectrum off by O(dt)), "
              "lm (Leimkuhler-Matthews: the mean of this and the next step's draw; exact for linear modes) or midpoint "
              "(Delong et al. 2014: predictor-corrector, two tension solves per step; midpoint.py)",
              choices=("euler", "lm", "midpoint")),
    Parameter("noise_drift_every", 1, "int", "thermal noise: steps between the Ito drift's random finite differences "
              "(two constrained solves each), applied with that weight; 10 heats the shortest modes by 3-15% at "
              "N = 32; 0: no drift (paired runs at N = 32, either coupling: spectrum and centroid D within 1.1%; 3x "
              "fewer solves; docs/history/thermal.md)", "", 0, 1000),
    Parameter("step_control", "limits", "str", "inextensible, adaptive dt, no noise: limits (forward Euler, the step "
              "the smallest of the stability and accuracy limits) or error (explicit midpoint with an embedded Euler "
              "error estimate: the step follows step_tol on the wrinkle amplitudes in place of the growth and flow "
              "limits; embedded_midpoint.py, docs/explanation/step-control.md)", choices=("limits", "error")),
    Parameter("step_tol", 0.025, "float", "step_control error: relative tolerance on the wrinkle amplitudes (and "
              "the shape's deformation) of the first-order error estimate per step; a mode growing at rate r then "
              "takes r dt ~ sqrt(2 step_tol) per step; 0.025: halving it moved l_* by 0.13% at 32^3 "
              "(docs/explanation/step-control.md)", "", 0.0, 1.0, lo_open=True),
    Parameter(
        "store_velocity", False, "bool", "write the membrane velocity of every frame (node_ux, node_uy, node_uz)"
    ),
)

#: parameters of a vesicle mesh (``vesicle mesh``, the workflow's ``mesh`` section); Delta comes from the sweep
MESH_PARAMETERS: tuple[Parameter, ...] = (
    Parameter(
        "family",
        "quasiuniform",
        "str",
        "mesh family (quasiuniform has no icosahedral bias; config/README.md, Why quasi-uniform)",
        choices=("icosphere", "quasiuniform"),
    ),
    Parameter(
        "level",
        4,
        "int",
        "icosphere level: 10 4^level + 2 vertices (42, 162, 642, 2562, 10242, 40962 ...); also the vertex count of "
        "the quasi-uniform family when n_vertices is null (`vesicle mesh --level` without --n-vertices)",
        "",
        0,
        9,
    ),
    Parameter("n_vertices", 9512, "int", "vertex count of the quasi-uniform family (null: that of level); ignored by "
              "the icosphere. The default, 9512, is a mean edge of ~h on the default grid (N = 128, L = 5 R: "
              "mesh.vertices_for_edge), what the sharp coupling needs", "", 12, 20000000, nullable=True),
    Parameter("seed", 0, "int", "seed of the quasi-uniform family", "", 0, 2**31 - 1),
    Parameter("lloyd_steps", 8, "int", "Lloyd relaxation steps (quasi-uniform)", "", 0, 1000),
    Parameter("radius", 1.0, "float", "equivalent radius, volume 4/3 pi R^3 (the solver's length unit: keep 1)", "R",
              0.0, None, lo_open=True),
)

RUN = {p.name: p for p in RUN_PARAMETERS}
MESH = {p.name: p for p in MESH_PARAMETERS}
#: the keys the workflow passes per case, in table order
WORKFLOW_RUN_KEYS = tuple(p.name for p in RUN_PARAMETERS if p.workflow)


def defaults(table=RUN_PARAMETERS, workflow_only=False) -> dict:
    return {p.name: p.default for p in table if p.workflow or not workflow_only}


def check_all(values: dict, table=RUN_PARAMETERS, where: str = "") -> dict:
    """Check a dict of parameters against a table: unknown names and bad values raise ConfigError."""
    known = {p.name: p for p in table}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ConfigError(f"{where}unknown parameter(s) {unknown}; allowed: {sorted(known)}")
    return {k: known[k].check(v) for k, v in values.items()}
