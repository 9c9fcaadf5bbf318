# IBM runs: one job per case. `vesicle run` checkpoints into the run directory and resumes when the job is
# restarted (checkpoint.nc and trajectory.partial.nc are not outputs, so Snakemake leaves them alone); the
# trajectory appears only when the run is complete. Every run parameter is passed explicitly, so a change of
# any of them in the config reruns exactly the cases it applies to.
#
# Benchmark or cache: Snakemake refuses a rule that has both a benchmark and a cache directive (a result taken
# from the cache has no timing to put in the benchmark file). So `simulate` is defined with
#   cache: "omit-software"  when the workflow runs with --cache (all eligible rules, or `--cache simulate`), and
#   benchmark: results/benchmarks/simulate/{case_id}.tsv  otherwise (the default).
# The run's own timing is recorded in every trajectory.nc either way (attrs steps, wall_time_s_last_call).

SIMULATE_CACHED = _caching_requested("simulate")

SIMULATE_PARAMS = dict(
    outdir=lambda wildcards, output: os.path.dirname(output.trajectory),
    chi=case_value("chi"),
    **{key: run_value(key) for key in RUN_KEYS},
)

SIMULATE_SHELL = (
    "vesicle run {input.mesh} -o {params.outdir} --quiet --set chi={params.chi}"
    " --set N={params.N} --set L={params.L} --set Re={params.Re}"
    " --set Lambda={params.Lambda} --set K_volume={params.K_volume} --set K_area={params.K_area}"
    " --set area_model={params.area_model} --set kernel={params.kernel} --set scheme={params.scheme}"
    " --set projection_refresh={params.projection_refresh} --set stretch={params.stretch}"
    " --set stationary_tol={params.stationary_tol} --set t_end={params.t_end} --set dt={params.dt}"
    " --set dt_safety={params.dt_safety} --set output_every={params.output_every}"
    " --set checkpoint_every={params.checkpoint_every} --set max_drift={params.max_drift}"
    " --set backend={params.backend} --set dtype={params.dtype} --set fft_workers={params.fft_workers}"
    " --set cg_tol={params.cg_tol} --set cg_maxiter={params.cg_maxiter} --set cg_precond={params.cg_precond}"
    " --set dt_growth={params.dt_growth}"
    " > {log} 2>&1"
)

if SIMULATE_CACHED:

    rule simulate:
        input:
            mesh=mesh_of_case,
        output:
            trajectory="results/runs/{case_id}/trajectory.nc",
        log:
            "results/logs/simulate/{case_id}.log",
        params:
            **SIMULATE_PARAMS,
        threads: lambda wildcards: int(CASES[wildcards.case_id]["run"]["fft_workers"])
        resources:
            gpu=sim_resource("gpu"),
            mem_mb=sim_resource("mem_mb"),
            runtime=sim_resource("runtime"),
        cache: "omit-software"
        conda:
            "../envs/vesicle.yaml"
        shell:
            SIMULATE_SHELL

else:

    rule simulate:
        input:
            mesh=mesh_of_case,
        output:
            trajectory="results/runs/{case_id}/trajectory.nc",
        log:
            "results/logs/simulate/{case_id}.log",
        benchmark:
            "results/benchmarks/simulate/{case_id}.tsv"
        params:
            **SIMULATE_PARAMS,
        threads: lambda wildcards: int(CASES[wildcards.case_id]["run"]["fft_workers"])
        resources:
            gpu=sim_resource("gpu"),
            mem_mb=sim_resource("mem_mb"),
            runtime=sim_resource("runtime"),
        conda:
            "../envs/vesicle.yaml"
        shell:
            SIMULATE_SHELL
