"""RunConfig is written out as a class (editors and type checkers see its fields) and must stay the parameter table:
the same names in the same order, the same defaults and the types of each parameter's kind."""

import dataclasses
import pickle

import pytest

from vesicle_core.errors import ConfigError
from vesicle_core.model.parameters import RUN_PARAMETERS, Parameter
from vesicle_core.model.run_config import RunConfig

KINDS = {"float": float, "int": int, "str": str, "bool": bool}


def expected_type(p: Parameter):
    """The annotation a parameter's field must carry: its kind, ``| str`` when it also takes words (dt: "power"),
    ``| None`` when nullable."""
    t = KINDS[p.kind]
    if p.also:
        t = t | str
    if p.nullable:
        t = t | None
    return t


def table_mismatches(cls=RunConfig, table=RUN_PARAMETERS) -> list[str]:
    """Every way the dataclass's fields differ from the table (empty when they agree)."""
    got = dataclasses.fields(cls)
    out = []
    names, want = [f.name for f in got], [p.name for p in table]
    if names != want:
        out.append(f"fields {names} != table {want}")
    by_name = {f.name: f for f in got}
    for p in table:
        f = by_name.get(p.name)
        if f is None:
            continue
        if f.default is dataclasses.MISSING or f.default_factory is not dataclasses.MISSING:
            out.append(f"{p.name}: no plain default")
        elif type(f.default) is not type(p.default) or f.default != p.default:
            out.append(f"{p.name}: default {f.default!r} != table {p.default!r}")
        if f.type != expected_type(p):
            out.append(f"{p.name}: type {f.type!r} != {expected_type(p)!r}")
    return out


def test_runconfig_fields_are_the_table():
    assert dataclasses.is_dataclass(RunConfig) and RunConfig.__dataclass_params__.frozen
    assert table_mismatches() == []
    for p in RUN_PARAMETERS:
        assert p.check(p.default) == p.default, p.name  # every default passes its own check unchanged
        RunConfig(**{p.name: p.default})


def _variant(change):
    """A RunConfig-like dataclass whose fields are RunConfig's with one change (to show the comparison bites)."""
    spec = [(f.name, f.type, dataclasses.field(default=f.default)) for f in dataclasses.fields(RunConfig)]
    return dataclasses.make_dataclass("Variant", change(spec), frozen=True)


@pytest.mark.parametrize(
    "change",
    [
        lambda s: s + [("extra", int, dataclasses.field(default=0))],  # added
        lambda s: s[:-1],  # removed
        lambda s: [s[1], s[0], *s[2:]],  # reordered
        lambda s: [(n, t, dataclasses.field(default=64)) if n == "N" else (n, t, d) for n, t, d in s],  # default
        lambda s: [(n, t, dataclasses.field(default=1)) if n == "stretch" else (n, t, d) for n, t, d in s],  # 1 != 1.0
        lambda s: [(n, float, d) if n == "dt" else (n, t, d) for n, t, d in s],  # type: dt also takes words
        lambda s: [(n, int, d) if n == "tension_l_max" else (n, t, d) for n, t, d in s],  # type: not nullable
    ],
    ids=["added", "removed", "reordered", "default", "default-type", "dt-type", "nullable"],
)
def test_the_comparison_sees_every_drift(change):
    assert table_mismatches(_variant(change))


def test_runconfig_checks_and_derives():
    c = RunConfig(N=128.0, L=5, dt=1e-4)
    assert c.N == 128 and type(c.N) is int and c.h == 5 / 128
    assert RunConfig(dt="formula").dt == "formula"
    with pytest.raises(ConfigError, match="dt"):
        RunConfig(dt="adaptive")
    with pytest.raises(ConfigError, match="inextensible"):
        RunConfig(scheme="inextensible", Re=1e-3)
    for ale in ("area", "shape", "quality"):  # the triangle tension holds every triangle itself: no mesh motion for it
        with pytest.raises(ConfigError, match=f"mesh_ale '{ale}' applies to tension_space 'harmonic'"):
            RunConfig(scheme="inextensible", tension_space="triangle", mesh_ale=ale)
    with pytest.raises(ConfigError, match="mesh_ale"):
        RunConfig(mesh_ale="angles")
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.N = 64
    assert RunConfig.from_dict({"N": 64}) == RunConfig(N=64)
    with pytest.raises(ConfigError, match="unknown run parameter"):
        RunConfig.from_dict({"n": 64})
    attrs = c.as_attrs()
    assert attrs["Lambda"] == "default" and attrs["Lambda_eff"] == c.Lambda_eff and attrs["h"] == c.h
    assert pickle.loads(pickle.dumps(c)) == c
    assert RunConfig.__module__ == "vesicle_core.model.run_config"


def test_from_attrs_gives_back_the_config_a_trajectory_stored(tmp_path):
    """as_attrs -> a trajectory's netCDF attributes (booleans as strings, None as "default") -> from_attrs is the
    identity; keys that are not run parameters are ignored."""
    import xarray as xr

    cfg = RunConfig(chi=3.0, N=32, scheme="inextensible", kT=0.04, noise_seed=9, noise_scheme="midpoint",
                    store_velocity=True, tension_space="harmonic", tension_l_max=None, dt=2.5e-4, seed_spectrum="mesh")
    attrs = {k: (str(v) if isinstance(v, bool) else v) for k, v in cfg.as_attrs().items()}
    xr.Dataset(attrs={**attrs, "title": "x"}).to_netcdf(tmp_path / "t.nc")
    back = RunConfig.from_attrs(xr.open_dataset(tmp_path / "t.nc").attrs)
    assert back == cfg
    assert back.store_velocity is True and back.tension_l_max is None and isinstance(back.N, int)


def test_from_attrs_reads_a_missing_key_as_its_default_of_the_time():
    """A trajectory written before a key existed lacks it, and ran with that key's default of the time: the defaults
    before the recommended method became the default (coupling kernel, tension_space triangle, ...), not today's."""
    from vesicle_core.model.run_config import DEFAULTS_BEFORE_RECOMMENDED

    old = RunConfig.from_attrs({"chi": 67.0, "N": 64, "scheme": "inextensible"})
    assert (old.coupling, old.kernel, old.tension_space, old.mesh_ale, old.seed_spectrum, old.t_end) == (
        "kernel", "peskin4", "triangle", "none", "mesh", 1.5)
    assert old.N == 64 and old.scheme == "inextensible"  # what the file records wins
    assert all(RunConfig().__getattribute__(k) != v for k, v in DEFAULTS_BEFORE_RECOMMENDED.items())
    from vesicle_core.model.run_config import legacy_config

    assert legacy_config(N=16) == old.__class__(**{**DEFAULTS_BEFORE_RECOMMENDED, "N": 16})
