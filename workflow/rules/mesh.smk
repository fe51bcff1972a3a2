rule mesh:
    output: f"{RESULTS}/mesh/{{name}}.nc"
    log: f"{RESULTS}/logs/mesh/{{name}}.log"
    benchmark: f"{RESULTS}/benchmarks/mesh/{{name}}.tsv"
    priority: UPSTREAM_PRIORITY
    params:
        spec=job("mesh"),
        code=STAGE_CODE["mesh"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/mesh.py"
