# Helpers and the sweep table. No rules in this file (Snakemake's linter asks for functions and rules apart).
#
# The sweep table CASES has one row per simulation case: (Delta, S or chi, N, mesh) from config["sweep"] merged
# with the global mesh/run sections. Ids come from vesicle_core.data.case_ids (readable, built from the physical
# parameters only, e.g. D0.116_S553_N32_L3), so the same parameters always map to the same files and a change
# of one S plans jobs for that point only. Meshes are keyed by mesh parameters alone and shared between flow
# strengths; PA datasets are keyed by (Delta, S) alone.

import os
import re

from vesicle_core.data.case_ids import case_id as _case_id
from vesicle_core.data.case_ids import mesh_id as _mesh_id
from vesicle_core.data.case_ids import theory_id as _theory_id
from vesicle_core.model.units import S_from_chi, chi_from_S

# run and mesh parameters: names and defaults from their one table (vesicle_core/model/parameters.py)
from vesicle_core.model.parameters import MESH_PARAMETERS, RUN_PARAMETERS
from vesicle_core.model.parameters import WORKFLOW_RUN_KEYS as RUN_KEYS
from vesicle_core.model.parameters import defaults as _defaults


def fill_defaults(cfg):
    """The run and mesh sections with the table's defaults under the config's values (the schema has none)."""
    cfg["run"] = {**_defaults(RUN_PARAMETERS, workflow_only=True), **cfg.get("run", {})}
    cfg["mesh"] = {**_defaults(MESH_PARAMETERS), **cfg.get("mesh", {})}
    return cfg


def _plain(value):
    """A config value as a plain Python scalar (YAML may give numpy-free ints/floats already)."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int):
        return int(value)
    return float(value)


def _mesh_params(group, base):
    mesh = {**base, **group.get("mesh", {})}
    if mesh["family"] == "quasiuniform" and not mesh.get("n_vertices"):
        mesh["n_vertices"] = 10 * 4 ** int(mesh["level"]) + 2
    if mesh["family"] == "icosphere":
        # icosphere: the vertex count follows from the level; seeds and Lloyd steps do not apply
        mesh.update(n_vertices=10 * 4 ** int(mesh["level"]) + 2, seed=0, lloyd_steps=0)
    return mesh


def _members(gi, group, flows, run):
    """(kind, value, noise_seed) of every case of a group: one per flow value, times the group's noise_seeds (an
    ensemble, kT > 0) or the run's single noise_seed."""
    seeds = group.get("noise_seeds")
    if seeds is not None and not float(run["kT"]) > 0:
        raise ValueError(
            f"config: sweep[{gi}] gives noise_seeds but kT = {run['kT']}: an ensemble needs thermal noise "
            "(run.kT > 0, scheme: inextensible)"
        )
    seeds = [int(s) for s in seeds] if seeds is not None else [int(run["noise_seed"])]
    return [(kind, value, s) for kind, value in flows for s in seeds]


def build_sweep(cfg):
    """(cases, meshes, theories): dicts id -> parameters, from a validated config."""
    cases, meshes, theories = {}, {}, {}
    th = cfg["theory"]
    for gi, group in enumerate(cfg["sweep"]):
        delta = float(group["delta"])
        mesh = _mesh_params(group, cfg["mesh"])
        run = {**cfg["run"], **group.get("run", {})}
        if "N" in group:
            run["N"] = group["N"]
        run = {k: _plain(run[k]) for k in RUN_KEYS}
        mid = _mesh_id(delta, mesh["family"], mesh["level"], mesh["n_vertices"], mesh["seed"], mesh["radius"])
        meshes[mid] = {
            "delta": delta,
            "family": mesh["family"],
            "level": int(mesh["level"]),
            "n_vertices": int(mesh["n_vertices"]),
            "seed": int(mesh["seed"]),
            "lloyd_steps": int(mesh["lloyd_steps"]),
            "radius": float(mesh["radius"]),
        }
        if "S" in group:
            flows = [("S", float(s)) for s in group["S"]]
        else:
            flows = [("chi", float(c)) for c in group["chi"]]
        for kind, value, noise_seed in _members(gi, group, flows, run):
            S = value if kind == "S" else S_from_chi(value, delta)
            chi = chi_from_S(value, delta) if kind == "S" else value
            member = {**run, "noise_seed": noise_seed}
            cid = _case_id(
                delta,
                **{kind: value},
                N=run["N"],
                family=mesh["family"],
                level=mesh["level"],
                n_vertices=mesh["n_vertices"] if mesh["family"] == "quasiuniform" else None,
                seed=mesh["seed"] if mesh["family"] == "quasiuniform" else 0,
                tag=group.get("tag"),
                kT=run["kT"],
                noise_seed=noise_seed,
            )
            if cid in cases:
                raise ValueError(
                    f"config: sweep[{gi}] repeats case {cid} (same Delta, flow, N and mesh as another entry); "
                    "give one of the groups a 'tag'"
                )
            tid = _theory_id(delta, S, th["seed"])
            cases[cid] = {
                "delta": delta,
                "S": float(S),
                "chi": float(chi),
                "mesh_id": mid,
                "theory_id": tid,
                "run": member,
                "group": gi,
            }
            theories.setdefault(tid, {"delta": delta, "S": float(S)})
        for s in group.get("pa_S", []):
            theories.setdefault(_theory_id(delta, float(s), th["seed"]), {"delta": delta, "S": float(s)})
    return cases, meshes, theories


CASES, MESHES, THEORIES = build_sweep(fill_defaults(config))


def _alternation(ids):
    return "|".join(re.escape(i) for i in sorted(ids, key=len, reverse=True))


wildcard_constraints:
    case_id=_alternation(CASES),
    mesh_id=_alternation(MESHES),
    theory_id=_alternation(THEORIES),


# --------------------------------------------------------------------------- parameter accessors for params:
def case_value(key):
    """params: accessor of one sweep-table field of the case (plain float/str)."""
    return lambda wildcards: CASES[wildcards.case_id][key]


def case_run_yaml(wildcards):
    """params: every run parameter of the case (chi included) as the YAML text of `vesicle run -c`."""
    import yaml

    case = CASES[wildcards.case_id]
    return yaml.safe_dump({"chi": case["chi"], **case["run"]}, sort_keys=False)


def mesh_value(key):
    return lambda wildcards: MESHES[wildcards.mesh_id][key]


def theory_value(key):
    return lambda wildcards: THEORIES[wildcards.theory_id][key]


def option(flag, value):
    """An optional command-line flag: '' when value is None/False, '--flag' for True, else '--flag v1 v2'."""
    if value is None or value is False:
        return ""
    if value is True:
        return flag
    if isinstance(value, (list, tuple)):
        return f"{flag} " + " ".join(str(v) for v in value)
    return f"{flag} {value}"


def sim_resource(key):
    return lambda wildcards: int(config["resources"]["simulate"][key])


def ana_resource(key):
    return lambda wildcards: int(config["resources"]["analysis"][key])


# Scheduling. A run's cost grows like N^3 log N per Stokes solve times a step count that also grows with N, so
# a sweep's largest grids are its longest jobs by far (convergence.yaml: each 256^3 run ~50 min, each 128^3 run
# 3-12 min). Snakemake picks ready jobs in an arbitrary order among equal priorities; starting the longest first
# (longest-processing-time scheduling) keeps every core busy to the end instead of leaving one 256^3 run alone.
# Meshes take seconds and gate the runs, so they go before any run.
MESH_PRIORITY = 100_000


def sim_priority(wildcards):
    return int(CASES[wildcards.case_id]["run"]["N"])


# --------------------------------------------------------------------------- paths
VEC = config["figures"]["vector_format"]


def mesh_of_case(wildcards):
    return f"results/meshes/{CASES[wildcards.case_id]['mesh_id']}.nc"


def theory_of_case(wildcards):
    return f"results/theory/{CASES[wildcards.case_id]['theory_id']}.nc"


def all_meshes():
    return [f"results/meshes/{m}.nc" for m in MESHES]


def all_trajectories():
    return [f"results/runs/{c}/trajectory.nc" for c in CASES]


def all_spectra():
    return [f"results/runs/{c}/spectra.nc" for c in CASES]


def all_microscopes():
    return [f"results/runs/{c}/microscope.nc" for c in CASES]


def morphology_report_path():
    return config["morphology_report"].get("report", "docs/validation_morphology.md")


def morphology_report_args(wildcards, input):
    """--case CASE_ID MICROSCOPE SPECTRA per case of the sweep (rule morphology_report)."""
    return " ".join(f"--case {c} {input[f'mic_{c}']} {input[f'spec_{c}']}" for c in CASES)


def morphology_report_inputs():
    out = {}
    for c in CASES:
        out[f"mic_{c}"] = f"results/runs/{c}/microscope.nc"
        out[f"spec_{c}"] = f"results/runs/{c}/spectra.nc"
    return out


def all_theories():
    return [f"results/theory/{t}.nc" for t in THEORIES]


def case_figures(case):
    return [
        f"results/figures/{case}/dynamics.png",
        f"results/figures/{case}/dynamics.{VEC}",
        f"results/figures/{case}/wrinkles.png",
        f"results/figures/{case}/views.png",
        f"results/figures/{case}/snapshots.png",
        f"results/figures/{case}/microscope.png",
    ]


def all_figures():
    out = ["results/figures/lstar_vs_S.png", f"results/figures/lstar_vs_S.{VEC}"]
    for c in CASES:
        out += case_figures(c)
    return out


def all_targets():
    extra = [config["validation"].get("report", "docs/validation.md")] if "validation" in config else []
    if "morphology_report" in config:
        extra.append(morphology_report_path())
    return ["results/catalog.csv", "results/catalog.parquet", "results/catalog.json", *all_figures(), *extra]


def _caching_requested(rule_name):
    """True when Snakemake runs with --cache for this rule (--cache alone means every eligible rule)."""
    settings = getattr(workflow, "workflow_settings", None)
    rules = getattr(settings, "cache", None)
    return rules is not None and (len(rules) == 0 or rule_name in rules)


# --------------------------------------------------------------------------- validation study (rules/validation.smk)
def _case_tag(cid):
    return config["sweep"][CASES[cid]["group"]].get("tag")


def validation_group(cid):
    """The report's role of a case, from its tag: the ladder (its finest rung is the report's main sweep),
    seed and one-change variations, the periodic-box pair, the coarse copy, or the main sweep."""
    v = config["validation"]
    tag = _case_tag(cid)
    if v.get("ladder_tag") and tag == v["ladder_tag"]:
        # each Delta's finest rung is its main sweep (the elongated cases may stop at a coarser N)
        finest = max(
            CASES[c]["run"]["N"] for c in CASES if _case_tag(c) == tag and CASES[c]["delta"] == CASES[cid]["delta"]
        )
        return "fine" if CASES[cid]["run"]["N"] == finest else "ladder"
    if tag in v.get("seed_tags", []):
        return "seed"
    if tag in v.get("variation_tags", []):
        return "variation"
    if tag == v["coarse_tag"]:
        return "coarse"
    if tag in v["box_tags"]:
        return "box"
    return "fine"


def validation_inputs():
    out = {"fit": "results/fits/lstar_vs_S.nc", "figures": validation_figures()}
    for cid in CASES:
        out[f"traj_{cid}"] = f"results/runs/{cid}/trajectory.nc"
        out[f"spec_{cid}"] = f"results/runs/{cid}/spectra.nc"
        out[f"theo_{cid}"] = f"results/theory/{CASES[cid]['theory_id']}.nc"
    return out


def _fine_cases_at(S_values):
    return [c for c in CASES if validation_group(c) == "fine" and any(abs(CASES[c]["S"] - s) < 1e-6 for s in S_values)]


def validation_figures():
    figs = ["results/figures/lstar_vs_S.png"]
    for c in _fine_cases_at(config["validation"]["dynamics_S"]):
        figs.append(f"results/figures/{c}/dynamics.png")
    for c in _fine_cases_at(config["validation"]["detail_S"]):
        figs += [f"results/figures/{c}/wrinkles.png", f"results/figures/{c}/views.png"]
    return figs


def _caption(path):
    if path.endswith("lstar_vs_S.png"):
        return "Fig. 4 style: l_* against S, simulation and PA, fitted exponents"
    case = os.path.basename(os.path.dirname(path))
    kind = os.path.splitext(os.path.basename(path))[0]
    text = {
        "dynamics": "Fig. 3/5 style: sigma(t), Delta_2, Delta_l* (simulation vs PA)",
        "wrinkles": "Fig. 8 style: A_p maps, A_p-bar(t), Delta~_l(t)",
        "views": "Fig. 6e/7c style: six views coloured by local tension",
    }[kind]
    return f"{text}, {case}"


def validation_args(wildcards, input):
    v = config["validation"]
    parts = []
    for cid in CASES:
        parts.append(
            f"--case {cid} {validation_group(cid)} {input[f'traj_{cid}']} {input[f'spec_{cid}']} "
            f"{input[f'theo_{cid}']}"
        )
    parts.append(f"--fit fine {input.fit}")
    box = [c for t in v["box_tags"] for c in CASES if _case_tag(c) == t]
    if len(box) == 2:
        parts.append(f"--box {input[f'traj_{box[0]}']} {input[f'traj_{box[1]}']}")
    for f in input.figures:
        parts.append(f"--figure {f} '{_caption(f)}'")
    parts.append(f"--resolution-note '{v['resolution_note']}'")
    if v.get("morphology_section"):
        parts.append(f"--morphology-section {v['morphology_section']}")
    return " ".join(parts)
