# What a phase-contrast microscope focused on the flow's plane sees of each run: outlines, k_*(t), crests and
# contour spectra (vesicle_core.analysis.microscope), reusing the ellipsoids that `vesicle decompose` fitted.


rule microscope:
    input:
        trajectory="results/runs/{case_id}/trajectory.nc",
        spectra="results/runs/{case_id}/spectra.nc",
    output:
        microscope="results/runs/{case_id}/microscope.nc",
    log:
        "results/logs/microscope/{case_id}.log",
    params:
        stride=config["analysis"]["stride"],
    resources:
        mem_mb=ana_resource("mem_mb"),
        runtime=ana_resource("runtime"),
    shell:
        "vesicle microscope {input.trajectory} --spectra {input.spectra} -o {output.microscope}"
        " --stride {params.stride} --quiet > {log} 2>&1"
