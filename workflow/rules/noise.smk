# Noisy ensembles (issue 49): the stochastic PA beside every noisy point, the ensemble analysis from the catalog
# (vesicle_core.analysis.noise_ensembles) and its figures (vesicle_core.viz.noise_figures). Helpers:
# rules/noise_common.smk.


rule stochastic_pa:
    output:
        pa="results/noise/pa/{spa_id}.nc",
    log:
        "results/logs/noise/pa_{spa_id}.log",
    params:
        delta=spa_value("delta"),
        S=spa_value("S"),
        kT=spa_value("kT"),
        grid=spa_grid_options,
        seeds=config.get("noise", {}).get("pa_seeds", 16),
        n_steps=config.get("noise", {}).get("pa_n_steps", 4000),
        l_max=option("--l-max", config.get("noise", {}).get("pa_l_max")),
    resources:
        mem_mb=ana_resource("mem_mb"),
        runtime=ana_resource("runtime"),
    shell:
        "vesicle stochastic-pa --delta {params.delta} --S {params.S} --kT {params.kT} --seeds {params.seeds}"
        " --n-steps {params.n_steps} {params.l_max} {params.grid} -o {output.pa} > {log} 2>&1"


rule noise_analysis:
    input:
        catalog="results/catalog.csv",
        pa=all_spa(),
    output:
        ensembles="results/noise/ensembles.nc",
    log:
        "results/logs/noise/ensembles.log",
    params:
        n_boot=config.get("noise", {}).get("bootstrap", 2000),
        confidence=config.get("noise", {}).get("confidence", 0.95),
    shell:
        "vesicle noise analyse {input.catalog} --pa {input.pa} --n-boot {params.n_boot}"
        " --confidence {params.confidence} -o {output.ensembles} > {log} 2>&1"


rule noise_figures:
    input:
        ensembles="results/noise/ensembles.nc",
        catalog="results/catalog.csv",
        fit="results/fits/lstar_vs_S.nc",
        pa=all_spa(),
    output:
        figures=noise_figures(),
    log:
        "results/logs/noise/figures.log",
    params:
        dpi=config["figures"]["dpi"],
    shell:
        "vesicle noise figures {input.ensembles} --catalog {input.catalog} --fit {input.fit} --pa {input.pa}"
        " --outdir results/figures/noise --dpi {params.dpi} > {log} 2>&1"


rule noise:
    input:
        noise_targets(),
