# What a phase-contrast microscope focused on the flow's plane sees of each run: outlines, k_*(t), crests and
# contour spectra, and the 3D wrinkle morphology with its pattern class at every 5th frame of the reversed flow, t_*
# and the paper's snapshot times (vesicle_core.analysis.microscope), reusing the ellipsoids that `vesicle decompose`
# fitted. With a `morphology_report` section (config/paper_converged.yaml), the paper's three pattern claims are
# decided from every case's microscope.nc: the section that docs/validation.md includes.


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


if "morphology_report" in config:

    rule morphology_report:
        input:
            unpack(lambda wildcards: morphology_report_inputs()),
        output:
            report=morphology_report_path(),
        log:
            "results/logs/morphology_report.log",
        params:
            args=morphology_report_args,
        shell:
            "vesicle pattern-claims {params.args} -o {output.report} > {log} 2>&1"
