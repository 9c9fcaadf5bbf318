# Figures (vesicle_core.viz.plots with matplotlib, vesicle_core.viz.render with pyvista off-screen), collected by
# `snakemake --report report.html` with the captions in workflow/report/.


rule figure_dynamics:
    input:
        spectra="results/runs/{case_id}/spectra.nc",
        theory=theory_of_case,
    output:
        png=report(
            "results/figures/{case_id}/dynamics.png",
            caption="../report/dynamics.rst",
            category="Fig. 3/5: wrinkling dynamics",
            subcategory="{case_id}",
            labels={"case": "{case_id}", "figure": "sigma, Delta_2, Delta_l*"},
        ),
        vector=f"results/figures/{{case_id}}/dynamics.{VEC}",
    log:
        "results/logs/figures/dynamics_{case_id}.log",
    params:
        dpi=config["figures"]["dpi"],
    shell:
        "vesicle figures dynamics {input.spectra} --theory {input.theory} --dpi {params.dpi}"
        " -o {output.png} {output.vector} > {log} 2>&1"


rule figure_wrinkles:
    input:
        spectra="results/runs/{case_id}/spectra.nc",
    output:
        png=report(
            "results/figures/{case_id}/wrinkles.png",
            caption="../report/wrinkles.rst",
            category="Fig. 8: wrinkle amplitude",
            subcategory="{case_id}",
            labels={"case": "{case_id}", "figure": "A_p maps, A_p-bar, Delta~_l"},
        ),
    log:
        "results/logs/figures/wrinkles_{case_id}.log",
    params:
        dpi=config["figures"]["dpi"],
        times=option("--times", config["figures"]["map_times"]),
    shell:
        "vesicle figures wrinkles {input.spectra} {params.times} --dpi {params.dpi} -o {output.png} > {log} 2>&1"


rule figure_views:
    input:
        trajectory="results/runs/{case_id}/trajectory.nc",
        spectra="results/runs/{case_id}/spectra.nc",
    output:
        png=report(
            "results/figures/{case_id}/views.png",
            caption="../report/views.rst",
            category="Figs. 6e/7c: membrane and local tension",
            subcategory="{case_id}",
            labels={"case": "{case_id}", "figure": "six views"},
        ),
    log:
        "results/logs/figures/views_{case_id}.log",
    params:
        time=option("--time", config["figures"]["render_time"]),
        width=config["figures"]["render_size"][0],
        height=config["figures"]["render_size"][1],
    shell:
        "vesicle figures views {input.trajectory} --spectra {input.spectra} {params.time}"
        " --size {params.width} {params.height} -o {output.png} > {log} 2>&1"


rule figure_snapshots:
    input:
        trajectory="results/runs/{case_id}/trajectory.nc",
        spectra="results/runs/{case_id}/spectra.nc",
    output:
        png=report(
            "results/figures/{case_id}/snapshots.png",
            caption="../report/snapshots.rst",
            category="Figs. 6e/7c: membrane and local tension",
            subcategory="{case_id}",
            labels={"case": "{case_id}", "figure": "snapshots"},
        ),
    log:
        "results/logs/figures/snapshots_{case_id}.log",
    params:
        times=option("--times", config["figures"]["snapshot_times"]),
        n=config["figures"]["n_snapshots"],
        frame=config["figures"]["render_size"][1] // 2,
    shell:
        "vesicle figures snapshots {input.trajectory} --spectra {input.spectra} {params.times} --n {params.n}"
        " --frame-size {params.frame} {params.frame} -o {output.png} > {log} 2>&1"


rule figure_lstar:
    input:
        fit="results/fits/lstar_vs_S.nc",
    output:
        png=report(
            "results/figures/lstar_vs_S.png",
            caption="../report/lstar.rst",
            category="Fig. 4: l_* against S",
            labels={"figure": "l_* vs S"},
        ),
        vector=f"results/figures/lstar_vs_S.{VEC}",
    log:
        "results/logs/figures/lstar_vs_S.log",
    params:
        dpi=config["figures"]["dpi"],
        measure=config["figures"]["lstar_measure"],
    shell:
        "vesicle figures lstar {input.fit} --measure {params.measure} --dpi {params.dpi}"
        " -o {output.png} {output.vector} > {log} 2>&1"


rule figure_microscope:
    input:
        microscope="results/runs/{case_id}/microscope.nc",
        trajectory="results/runs/{case_id}/trajectory.nc",
        spectra="results/runs/{case_id}/spectra.nc",
    output:
        png=report(
            "results/figures/{case_id}/microscope.png",
            caption="../report/microscope.rst",
            category="Fig. 6: what the microscope sees",
            subcategory="{case_id}",
            labels={"case": "{case_id}", "figure": "images, 3D views, k_* and l_*"},
        ),
    log:
        "results/logs/figures/microscope_{case_id}.log",
    params:
        dpi=config["figures"]["dpi"],
    shell:
        "vesicle figures microscope {input.microscope} {input.trajectory} --spectra {input.spectra}"
        " --dpi {params.dpi} -o {output.png} > {log} 2>&1"
