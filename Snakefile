# Entry point when snakemake runs from the project root; the workflow itself is workflow/Snakefile.
include: "workflow/Snakefile"


# Snakemake does not carry an included file's default target over to the including file, so the
# default (`snakemake --cores 2` without a target) is named here: everything that rule `all` asks for.
rule default:
    input:
        rules.all.input,
    default_target: True
