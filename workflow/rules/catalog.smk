# The data catalog: one CSV row per dataset, the same rows typed in Parquet, and an ESM-collection JSON beside them
# (vesicle_core.data.catalog).


rule catalog:
    input:
        meshes=all_meshes(),
        trajectories=all_trajectories(),
        spectra=all_spectra(),
        microscope=all_microscopes(),
        theory=all_theories(),
        fit="results/fits/lstar_vs_S.nc",
    output:
        csv="results/catalog.csv",
        json="results/catalog.json",
        parquet="results/catalog.parquet",
    log:
        "results/logs/catalog/catalog.log",
    shell:
        "vesicle catalog {input} -o {output.csv} --json {output.json} --parquet {output.parquet} > {log} 2>&1"
