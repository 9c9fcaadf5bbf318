# Helpers of the noisy-ensemble analysis (rules/noise.smk, issue 49). No rules in this file.
#
# Present only when the config has a `noise` section: beside every noisy point (Delta, S, N, mesh, kT) of the
# sweep, the stochastic PA with `pa_seeds` seeds in the continuum and on the run's grid (h = L / N, its kernel and
# coupling); then results/noise/ensembles.nc from the catalog and the figures in results/figures/noise/.


def _spa_ids():
    """stochastic PA id -> its parameters, one per (Delta, S, kT) in the continuum and per grid."""
    out = {}
    for c in CASES.values():
        run = c["run"]
        if not float(run["kT"]) > 0:
            continue
        base = f"D{c['delta']:g}_S{c['S']:g}_kT{float(run['kT']):g}"
        p = {"delta": c["delta"], "S": c["S"], "kT": float(run["kT"])}
        out[f"{base}_continuum"] = {**p, "grid_N": 0, "L": float(run["L"]), "kernel": "", "coupling": ""}
        grid = f"{base}_N{int(run['N'])}_L{float(run['L']):g}_{run['kernel']}_{run['coupling']}"
        out[grid] = {
            **p,
            "grid_N": int(run["N"]),
            "L": float(run["L"]),
            "kernel": run["kernel"],
            "coupling": run["coupling"],
        }
    return out


SPA = _spa_ids() if "noise" in config else {}


def spa_value(key):
    return lambda wildcards: SPA[wildcards.spa_id][key]


def spa_grid_options(wildcards):
    p = SPA[wildcards.spa_id]
    if not p["grid_N"]:
        return ""
    return f"--grid-N {p['grid_N']} --L {p['L']} --kernel {p['kernel']} --coupling {p['coupling']}"


def all_spa():
    return [f"results/noise/pa/{s}.nc" for s in SPA]


def noise_points():
    """Ids of the noisy points: a noisy case id without its seed (viz.noise_figures.point_id)."""
    return sorted({re.sub(r"_n\d+$", "", c) for c in CASES if float(CASES[c]["run"]["kT"]) > 0})


def noise_figures():
    if "noise" not in config or not SPA:
        return []
    out = ["results/figures/noise/lstar_vs_S.png", "results/figures/noise/lstar_hist.png"]
    return out + [f"results/figures/noise/dynamics_{p}.png" for p in noise_points()]


def noise_targets():
    return ["results/noise/ensembles.nc", *noise_figures()] if noise_figures() else []


wildcard_constraints:
    spa_id=_alternation(SPA) if SPA else "(?!x)x",
