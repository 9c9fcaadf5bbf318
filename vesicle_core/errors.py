"""The few exception types a user of vesicle_core sees."""

import math
import numbers


class VesicleError(Exception):
    """Base class of every error raised on purpose by vesicle_core."""


class ConfigError(VesicleError, ValueError):
    """A parameter or configuration value is missing, of the wrong type or out of range."""


class MeshError(VesicleError, ValueError):
    """A mesh is not a closed, consistently oriented genus-0 triangulation, or cannot be built."""


class NumericalInstability(VesicleError, RuntimeError):
    """A run produced NaN/Inf, blew up, or drifted beyond its allowed area/volume error."""


class MissingDependency(VesicleError, ImportError):
    """A package of an optional extra that a feature needs is not installed (the message names the extra)."""


def require(module: str, extra: str, feature: str):
    """Import and return ``module``, or raise MissingDependency saying which extra of the project installs it
    (the core needs numpy, scipy, xarray, netCDF4, PyYAML and tqdm only; pyproject.toml lists the extras)."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependency(
            f"{feature} needs {module.split('.')[0]} ({exc}): pip install 'vesicle-wrinkling[{extra}]', or "
            f"pip install -e '.[{extra}]' in a checkout") from None


def check_range(name, value, lo=None, hi=None, *, lo_open=False, hi_open=False, integer=False):
    """Return ``value`` if it lies in the allowed range, else raise ConfigError naming ``name``.

    The message states the allowed range so a user can fix the input without reading code.
    """
    import math

    def _range_text():
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        return f"{left}{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}{right}"

    if integer:
        if isinstance(value, bool) or not float(value).is_integer():
            raise ConfigError(f"{name} must be an integer in {_range_text()}, got {value!r}")
        value = int(value)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a number in {_range_text()}, got {value!r}") from None
    if math.isnan(v):
        raise ConfigError(f"{name} must be a number in {_range_text()}, got NaN")
    bad = (lo is not None and (v < lo or (lo_open and v == lo))) or (
        hi is not None and (v > hi or (hi_open and v == hi))
    )
    if bad:
        raise ConfigError(f"{name} must lie in {_range_text()}, got {value!r}")
    return value


def check_choice(name, value, allowed):
    """``value`` if it is one of ``allowed``, else ConfigError naming the field and the allowed values."""
    if value not in allowed:
        raise ConfigError(f"{name} must be one of {', '.join(map(repr, allowed))}, got {value!r}")
    return value


#: the largest counter / seed a Philox key or numpy generator takes
_U64 = 2**64 - 1


def check_counter(name, value):
    """A non-negative integer below 2^64 (numbers.Integral, or a float with an integer value), else ConfigError naming
    ``name``. Strings and booleans are refused even when they look like integers."""
    msg = f"{name} must be an integer in [0, {_U64}], got {value!r}"
    if isinstance(value, bool) or type(value).__name__ == "bool_" or not isinstance(value, numbers.Real):
        raise ConfigError(msg)
    if isinstance(value, numbers.Integral):
        v = int(value)
    else:
        f = float(value)
        if not math.isfinite(f) or not f.is_integer():
            raise ConfigError(msg)
        v = int(f)
    if not 0 <= v <= _U64:
        raise ConfigError(msg)
    return v
