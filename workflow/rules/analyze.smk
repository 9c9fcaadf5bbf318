# Spherical-harmonic analysis of each run (eqs. 30-32): u_lm(t), Delta_l(t), t_*, l_*, A_p statistics and maps.


rule analyze:
    input:
        trajectory="results/runs/{case_id}/trajectory.nc",
    output:
        spectra="results/runs/{case_id}/spectra.nc",
    log:
        "results/logs/analyze/{case_id}.log",
    params:
        options=" ".join(
            filter(
                None,
                [
                    option("--l-max", config["analysis"]["l_max"]),
                    option("--map", config["analysis"]["map"]),
                ],
            )
        ),
        stride=config["analysis"]["stride"],
    resources:
        mem_mb=ana_resource("mem_mb"),
        runtime=ana_resource("runtime"),
    shell:
        "vesicle decompose {input.trajectory} -o {output.spectra} --stride {params.stride} {params.options}"
        " --quiet > {log} 2>&1"
