"""One home for every run and mesh parameter (vesicle_core/model/parameters.py): the schema, the CLI, the workflow
and the docs must agree with the table, and these tests fail on any drift (RunConfig's fields: test_run_config.py)."""

import math
from pathlib import Path

import jsonschema
import pytest
import yaml

from vesicle_core.errors import ConfigError
from vesicle_core.model import parameter_docs as D
from vesicle_core.model import parameters as P

ROOT = Path(__file__).resolve().parents[2]


def test_generated_files_are_current():
    hint = "run `python -m vesicle_core.model.parameter_docs --write`"
    assert (ROOT / D.SCHEMA_FILE).read_text() == D.schema_text(), hint
    text = (ROOT / D.README_FILE).read_text()
    for name in ("run", "mesh"):
        assert D.readme_block(name) in text, f"{D.README_FILE}: the {name} table is stale; run the generator"


def _probe_values(p):
    if p.kind == "bool":
        return [True, False, "yes", 1]
    if p.kind == "str":
        return [*p.choices, "no-such-choice"]
    vals = [p.default] if not isinstance(p.default, str) and p.default is not None else []
    for edge in (p.lo, p.hi):
        if edge is None:
            continue
        step = 1 if p.kind == "int" else max(abs(edge), 1.0) * 1e-6
        vals += [edge - step, edge, edge + step]
    if p.kind == "int":
        vals += [3.5]
    if p.multiple_of:
        vals += [p.lo + 1]
    return [int(v) if p.kind == "int" and float(v).is_integer() else v for v in vals]


@pytest.mark.parametrize("table, section", [(P.RUN_PARAMETERS, "run"), (P.MESH_PARAMETERS, "mesh")])
def test_schema_and_table_accept_the_same_values(table, section):
    schema = yaml.safe_load((ROOT / D.SCHEMA_FILE).read_text())["$defs"][section]["properties"]
    for p in table:
        if not p.workflow:
            assert p.name not in schema
            continue
        for v in _probe_values(p) + ([None] if p.nullable else []):
            try:
                p.check(v)
                ok = True
            except ConfigError:
                ok = False
            valid = jsonschema.Draft202012Validator(schema[p.name]).is_valid(v)
            assert ok == valid, (p.name, v, ok, valid)


def test_choices_match_the_code():
    from vesicle_core.geometry.mesh import FAMILIES
    from vesicle_core.model.resolution import KERNELS
    from vesicle_core.solver import membrane as B
    from vesicle_core.solver.integrators import SCHEMES
    from vesicle_core.solver.seeding import SEED_SPECTRA

    # one list of schemes: the table's choices are the model's list, and the solver has one class per name, in order
    assert P.RUN["scheme"].choices is P.SCHEMES
    assert tuple(SCHEMES) == P.SCHEMES
    assert all(cls.name == name for name, cls in SCHEMES.items())
    assert set(P.RUN["kernel"].choices) == set(KERNELS)
    assert set(P.RUN["area_model"].choices) == set(B.AREA_MODELS)
    assert set(P.RUN["seed_spectrum"].choices) == set(SEED_SPECTRA)
    assert set(P.MESH["family"].choices) == set(FAMILIES)


def test_cli_defaults_are_the_table():
    from vesicle_core.cli import build_parser
    from vesicle_core.cli.sim import mesh_resolution

    a = build_parser().parse_args(["mesh", "-o", "x.nc"])
    a.level, a.n_vertices = mesh_resolution(a.level, a.n_vertices)  # options not given: None until resolved
    for p in P.MESH_PARAMETERS:
        assert getattr(a, p.name) == p.default, p.name
    assert mesh_resolution(3, None) == (3, None)  # --level alone: the quasi-uniform count of that level


def test_workflow_fills_the_table_defaults():
    # the workflow's keys are the table's (chi comes from the sweep), in table order
    assert P.WORKFLOW_RUN_KEYS == tuple(p.name for p in P.RUN_PARAMETERS if p.name != "chi")
    smk = (ROOT / "workflow" / "rules" / "common.smk").read_text()
    assert "WORKFLOW_RUN_KEYS as RUN_KEYS" in smk and "_defaults(RUN_PARAMETERS" in smk


def test_each_default_has_one_home():
    # the schema (generated or hand-written) and the config docs carry no run or mesh defaults
    schema = yaml.safe_load((ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text())
    for section in ("run", "mesh"):
        assert "properties" not in schema["properties"][section]

    def keys(node):
        if isinstance(node, dict):
            for k, v in node.items():
                yield k
                yield from keys(v)
        elif isinstance(node, list):
            for v in node:
                yield from keys(v)

    assert "default" not in set(keys(yaml.safe_load((ROOT / D.SCHEMA_FILE).read_text())))


def test_bad_values_name_the_parameter_and_range():
    with pytest.raises(ConfigError, match=r"dt_growth.*\(0.0, 1.0\]"):
        P.RUN["dt_growth"].check(2.0)
    with pytest.raises(ConfigError, match="multiple of 2"):
        P.RUN["N"].check(33)
    with pytest.raises(ConfigError, match="unknown parameter"):
        P.check_all({"N": 32, "flux": 1})
    assert P.RUN["dt"].check("power") == "power" and math.isclose(P.RUN["dt"].check(1e-3), 1e-3)


def test_a_number_that_yaml_read_as_text_gets_a_hint():
    """PyYAML (YAML 1.1) reads `Lambda: 1.0e8` as the string '1.0e8'; the error says so and how to write it."""
    import yaml

    from vesicle_core.errors import ConfigError
    from vesicle_core.model.run_config import RunConfig

    value = yaml.safe_load("Lambda: 1.0e8")["Lambda"]
    assert value == "1.0e8"
    with pytest.raises(ConfigError, match=r"Lambda .*1\.0e\+8"):
        RunConfig(Lambda=value)
    with pytest.raises(ConfigError) as err:
        RunConfig(dt="fast")
    assert "YAML" not in str(err.value)  # text that is not a number gets no such hint
