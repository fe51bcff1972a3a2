rule measure:
    input: solution=lambda w: PLAN.jobs["measure"][f"{RESULTS}/measure/{w.key}.nc"].get("solution", [])
    output: f"{RESULTS}/measure/{{key}}.nc"
    log: f"{RESULTS}/logs/measure/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/measure/{{key}}.tsv"
    priority: UPSTREAM_PRIORITY
    params:
        spec=job("measure"),
        code=STAGE_CODE["measure"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/measure.py"
