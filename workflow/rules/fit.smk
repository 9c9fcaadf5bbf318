# Power laws across the sweep: l_* ~ S^b per (simulation | PA, Delta) group, and the stage-2 tension decay
# |sigma| ~ t^-a per case, both in one file (`vesicle fit`, vesicle_core.analysis.sweep_fits.sweep_fit_dataset).


rule fit:
    input:
        spectra=all_spectra(),
        theory=all_theories(),
    output:
        fit="results/fits/lstar_vs_S.nc",
    log:
        "results/logs/fit/lstar_vs_S.log",
    params:
        confidence=config["fit"]["confidence"],
    resources:
        mem_mb=ana_resource("mem_mb"),
        runtime=ana_resource("runtime"),
    shell:
        "vesicle fit {input.spectra} {input.theory} --confidence {params.confidence} -o {output.fit} > {log} 2>&1"
