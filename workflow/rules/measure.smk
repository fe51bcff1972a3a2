rule measure:
    input: solution=lambda w: PLAN.jobs["measure"][f"{RESULTS}/measure/{w.file}.nc"].get("solution", [])
    output: f"{RESULTS}/measure/{{file}}.nc"
    log: f"{RESULTS}/logs/measure/{{file}}.log"
    benchmark: f"{RESULTS}/benchmarks/measure/{{file}}.tsv"
    threads: THREADS
    resources:
        mem_mb=job_mem_mb("measure"),
        runtime=job_runtime("measure"),
    priority: UPSTREAM_PRIORITY
    params:
        spec=job("measure"),
        code=STAGE_CODE["measure"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/measure.py"
