# The validation study (issue 6): docs/validation.md and its figures from the produced datasets, via
# `vesicle report`. Active only when the config has a `validation` section (config/validation.yaml).
# Cases are grouped by the tag of their sweep group: `coarse_tag` -> convergence copy, `box_tags`
# (small box first) -> periodic-box test, untagged -> the fine sweep.


rule validation_report:
    input:
        unpack(lambda wildcards: validation_inputs()),
    output:
        report=config.get("validation", {}).get("report", "docs/validation.md"),
    log:
        "results/logs/validation/report.log",
    params:
        args=validation_args,
    shell:
        "vesicle report {params.args} -o {output.report} > {log} 2>&1"
