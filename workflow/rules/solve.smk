rule solve:
    input: mesh=lambda w: PLAN.jobs["solve"][f"{RESULTS}/solve/{w.file}.nc"]["mesh"]
    output: f"{RESULTS}/solve/{{file}}.nc"
    log: f"{RESULTS}/logs/solve/{{file}}.log"
    benchmark: f"{RESULTS}/benchmarks/solve/{{file}}.tsv"
    threads: THREADS
    resources:
        mem_mb=job_mem_mb("solve"),
        runtime=job_runtime("solve"),
    priority: UPSTREAM_PRIORITY
    params:
        spec=job("solve"),
        code=STAGE_CODE["solve"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/solve.py"
