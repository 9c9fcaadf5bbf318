# IBM runs: one job per case. `vesicle run` checkpoints into the run directory and resumes when the job is
# restarted (checkpoint.nc and trajectory.partial.nc are not outputs, so Snakemake leaves them alone); the
# trajectory appears only when the run is complete. Every run parameter is in the rule's params (run.yaml), so a
# change of any of them in the config reruns exactly the cases it applies to.
#
# Benchmark or cache: Snakemake refuses a rule that has both a benchmark and a cache directive (a result taken
# from the cache has no timing to put in the benchmark file). So `simulate` is defined with
#   cache: "omit-software"  when the workflow runs with --cache (all eligible rules, or `--cache simulate`), and
#   benchmark: results/benchmarks/simulate/{case_id}.tsv  otherwise (the default).
# The run's own timing is recorded in every trajectory.nc either way (attrs steps, wall_time_s_last_call).
# One definition with computed directive values does not work (checked on Snakemake 9.27): `cache: False` would
# switch caching off, but the benchmark directive has no "no file" value (None and [] raise AttributeError in
# Rule.benchmark; "" is taken with an "Empty file path" warning and only works because the empty path happens to
# be falsy), and a rule body cannot hold an `if`. The two copies share their params and shell command below; keep
# the rest equal.

SIMULATE_CACHED = _caching_requested("simulate")

SIMULATE_PARAMS = dict(
    outdir=lambda wildcards, output: os.path.dirname(output.trajectory),
    case=case_run_yaml,
)

# the case's parameters go to `vesicle run` as one file, run.yaml, kept in the run directory: the same command
# reruns the case by hand (`vesicle run <mesh> -o <dir> -c <dir>/run.yaml`). Its progress lines (every 5% of the
# simulated time: step, strain, tension, area drift, CG iterations, ETA) go to the log, so a long run can be
# watched with `tail -f results/logs/simulate/<case>.log`.
SIMULATE_SHELL = (
    "printf '%s' {params.case:q} > {params.outdir}/run.yaml"
    " && vesicle run {input.mesh} -o {params.outdir} -c {params.outdir}/run.yaml"
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
        priority: sim_priority
        resources:
            gpu=sim_resource("gpu"),
            mem_mb=sim_resource("mem_mb"),
            runtime=sim_resource("runtime"),
        cache: "omit-software"
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
        priority: sim_priority
        resources:
            gpu=sim_resource("gpu"),
            mem_mb=sim_resource("mem_mb"),
            runtime=sim_resource("runtime"),
        shell:
            SIMULATE_SHELL
