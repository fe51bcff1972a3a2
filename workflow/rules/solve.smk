rule solve:
    input: mesh=lambda w: PLAN.jobs["solve"][f"{RESULTS}/solve/{w.key}.nc"]["mesh"]
    output: f"{RESULTS}/solve/{{key}}.nc"
    log: f"{RESULTS}/logs/solve/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/solve/{{key}}.tsv"
    priority: UPSTREAM_PRIORITY
    params:
        spec=job("solve"),
        code=STAGE_CODE["solve"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/solve.py"
