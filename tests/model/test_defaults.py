"""One recommended method everywhere: the defaults of the run and mesh parameters (vesicle_core/model/parameters.py),
those of the workflow's schema (workflow/schemas/config.schema.yaml) and the default job (config/config.yaml) agree
on every key config.yaml sets, except the keys it lists under ``differs_from_default``, each with its reason. So
``vesicle run mesh.nc`` with no ``--set`` (and ``RunConfig()``) runs what the default job runs. The paper's own
method is run_config.PAPER_METHOD and config/paper_method.yaml."""

from dataclasses import replace
from pathlib import Path

import pytest
import yaml

from vesicle_core.model import parameters as P
from vesicle_core.model.run_config import PAPER_METHOD, RunConfig

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"


def _load(name):
    return yaml.safe_load((ROOT / "config" / name).read_text())


def _schema_defaults(node, schema):
    """{dotted key: default} of the leaves of a schema object (following local $refs)."""
    ref = node.get("$ref", "")
    if ref.startswith("#/"):
        target = schema
        for part in ref[2:].split("/"):
            target = target[part]
        node = {**target, **{k: v for k, v in node.items() if k != "$ref"}}
    out = {}
    for key, sub in node.get("properties", {}).items():
        if "properties" in sub or sub.get("$ref", "").startswith("#/"):
            out.update({f"{key}.{k}": v for k, v in _schema_defaults(sub, schema).items()})
        elif "default" in sub:
            out[key] = sub["default"]
    return out


def _flatten(values, prefix=""):
    out = {}
    for key, value in values.items():
        if isinstance(value, dict):
            out.update(_flatten(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def disagreements(cfg) -> dict:
    """{section.key: (value in cfg, default)} for every key of cfg whose value is not its default: the parameter
    table's for run and mesh (read from vesicle_core.model.parameters at call time), the schema's for the rest."""
    schema = yaml.safe_load(SCHEMA.read_text())
    tables = {"run": P.RUN_PARAMETERS, "mesh": P.MESH_PARAMETERS}
    out = {}
    for section, values in cfg.items():
        if section in ("sweep", "differs_from_default"):
            continue
        if section in tables:
            defaults = {p.name: p.default for p in tables[section]}
        else:
            defaults = _schema_defaults(schema["properties"][section], schema)
        for key, value in _flatten(values).items():
            default = defaults.get(key, "<no default>")
            if value != default:
                out[f"{section}.{key}"] = (value, default)
    return out


def check_default_job_agrees():
    cfg = _load("config.yaml")
    reasons = cfg.get("differs_from_default", {})
    found = disagreements(cfg)
    unexplained = {k: v for k, v in found.items() if k not in reasons}
    assert not unexplained, (f"config/config.yaml differs from the defaults on {unexplained} ((value, default)): "
                             "change the default in vesicle_core/model/parameters.py or the schema, or say why under "
                             "differs_from_default")
    stale = sorted(set(reasons) - set(found))
    assert not stale, f"config/config.yaml's differs_from_default lists {stale}, which agree with the defaults"
    assert all(isinstance(r, str) and len(r.split()) >= 5 for r in reasons.values()), "each reason is a sentence"


def test_library_schema_and_default_job_agree():
    check_default_job_agrees()


@pytest.mark.parametrize("table, key, value", [("RUN_PARAMETERS", "scheme", "projection"),
                                               ("RUN_PARAMETERS", "N", 32),
                                               ("RUN_PARAMETERS", "dtype", "float32"),
                                               ("MESH_PARAMETERS", "n_vertices", None)])
def test_the_agreement_check_fails_on_a_changed_default(monkeypatch, table, key, value):
    """A changed library default (or one that comes to agree with a listed difference) fails the check above."""
    changed = tuple(replace(p, default=value) if p.name == key else p for p in getattr(P, table))
    monkeypatch.setattr(P, table, changed)
    with pytest.raises(AssertionError, match=key):
        check_default_job_agrees()


def test_the_agreement_check_fails_on_a_changed_schema_default(monkeypatch, tmp_path):
    schema = yaml.safe_load(SCHEMA.read_text())
    schema["properties"]["theory"]["properties"]["n_out"]["default"] = 101
    changed = tmp_path / "config.schema.yaml"
    changed.write_text(yaml.safe_dump(schema))
    monkeypatch.setitem(globals(), "SCHEMA", changed)
    with pytest.raises(AssertionError, match="theory.n_out"):
        check_default_job_agrees()


def test_a_run_without_parameters_is_the_default_jobs():
    """RunConfig() (what `vesicle run mesh.nc` builds without --set) is config.yaml's run section, apart from the
    listed differences, and the default mesh has the edge ~h that its sharp coupling needs."""
    from vesicle_core.geometry.mesh import vertices_for_edge

    cfg = _load("config.yaml")
    listed = {k.split(".", 1)[1] for k in cfg["differs_from_default"] if k.startswith("run.")}
    default = RunConfig()
    for key, value in cfg["run"].items():
        if key not in listed:
            assert getattr(default, key) == value, key
    mesh = P.defaults(P.MESH_PARAMETERS)
    assert mesh["family"] == "quasiuniform"
    assert mesh["n_vertices"] == vertices_for_edge(default.h, mesh["radius"])


def test_paper_method_is_the_papers_and_differs_from_the_default():
    """config/paper_method.yaml runs run_config.PAPER_METHOD on a mesh of edge ~2h, on top of config.yaml (as
    Snakemake merges a --configfile), and every one of its keys changes a default."""
    from vesicle_core.geometry.mesh import vertices_for_edge
    from vesicle_core.model.units import chi_from_S

    base, paper = _load("config.yaml"), _load("paper_method.yaml")
    assert {k: paper["run"][k] for k in PAPER_METHOD} == PAPER_METHOD
    assert all(P.RUN[k].default != v for k, v in PAPER_METHOD.items())
    run = {**base["run"], **paper["run"]}
    h = run["L"] / run["N"]
    assert paper["mesh"]["n_vertices"] == vertices_for_edge(2 * h)
    for group in paper["sweep"]:
        for S in group["S"]:
            cfg = RunConfig.from_dict({**run, **group.get("run", {}), "chi": chi_from_S(S, group["delta"])})
            assert cfg.scheme == "explicit" and cfg.coupling == "kernel" and cfg.kernel == "peskin4"


def test_vesicle_run_without_set_runs_the_recommended_method(tmp_path, monkeypatch):
    """`vesicle run mesh.nc -o DIR` with no -c and no --set hands the solver RunConfig(): the default job's method."""
    from vesicle_core.cli import main
    from vesicle_core.geometry import mesh as Mm
    from vesicle_core.solver import simulate

    Mm.save(Mm.make_vesicle("icosphere", level=1), tmp_path / "mesh.nc")
    seen = {}
    monkeypatch.setattr(simulate, "run", lambda mesh, cfg, outdir, progress: seen.setdefault("cfg", cfg) and "x.nc")
    assert main(["run", str(tmp_path / "mesh.nc"), "-o", str(tmp_path / "run"), "--quiet"]) == 0
    cfg = seen["cfg"]
    assert cfg == RunConfig()
    assert (cfg.scheme, cfg.tension_space, cfg.mesh_ale, cfg.coupling, cfg.kernel, cfg.seed_spectrum, cfg.N) == (
        "inextensible", "harmonic", "quality", "sharp", "bao6", "thermal", 128)
