# Perturbation analysis (eqs. 11-12) for each (Delta, S) of the sweep and the extra PA-only points (pa_S).


rule theory:
    output:
        theory="results/theory/{theory_id}.nc",
    log:
        "results/logs/theory/{theory_id}.log",
    params:
        delta=theory_value("delta"),
        S=theory_value("S"),
        seed=config["theory"]["seed"],
        n_out=config["theory"]["n_out"],
        options=" ".join(
            filter(
                None,
                [
                    option("--l-max", config["theory"]["l_max"]),
                    option("--no-modes", not config["theory"]["store_modes"]),
                ],
            )
        ),
    resources:
        mem_mb=ana_resource("mem_mb"),
        runtime=ana_resource("runtime"),
    shell:
        "vesicle theory --delta {params.delta} --S {params.S} --seed {params.seed} --n-out {params.n_out}"
        " {params.options} -o {output.theory} > {log} 2>&1"
