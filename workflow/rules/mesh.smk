rule mesh:
    output: f"{RESULTS}/mesh/{{name}}.nc"
    log: f"{RESULTS}/logs/mesh/{{name}}.log"
    benchmark: f"{RESULTS}/benchmarks/mesh/{{name}}.tsv"
    threads: THREADS
    resources:
        mem_mb=lambda w: mem_mb(PLAN.jobs["mesh"][f"{RESULTS}/mesh/{w.name}.nc"]["level"]),
        runtime=lambda w: runtime_minutes("mesh", PLAN.jobs["mesh"][f"{RESULTS}/mesh/{w.name}.nc"]["level"]),
    priority: UPSTREAM_PRIORITY
    params:
        spec=job("mesh"),
        code=STAGE_CODE["mesh"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/mesh.py"
