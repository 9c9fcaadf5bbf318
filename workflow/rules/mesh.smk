# Meshes: one per (target Delta, family, resolution, seed, radius); shared by every flow strength and grid.


rule mesh:
    output:
        mesh="results/meshes/{mesh_id}.nc",
    log:
        "results/logs/mesh/{mesh_id}.log",
    params:
        family=mesh_value("family"),
        level=mesh_value("level"),
        n_vertices=mesh_value("n_vertices"),
        seed=mesh_value("seed"),
        lloyd_steps=mesh_value("lloyd_steps"),
        delta=mesh_value("delta"),
        radius=mesh_value("radius"),
    priority: MESH_PRIORITY
    resources:
        mem_mb=ana_resource("mem_mb"),
        runtime=ana_resource("runtime"),
    cache: "omit-software"
    shell:
        "vesicle mesh -o {output.mesh} --family {params.family} --level {params.level}"
        " --n-vertices {params.n_vertices} --seed {params.seed} --lloyd-steps {params.lloyd_steps}"
        " --delta {params.delta} --radius {params.radius} > {log} 2>&1"
