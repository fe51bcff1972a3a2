rule identify:
    input:
        measurements=lambda w: identify_spec(w)["measurements"],
        mesh=lambda w: identify_spec(w)["mesh"],
    output: f"{RESULTS}/identify/{{file}}.nc"
    log: f"{RESULTS}/logs/identify/{{file}}.log"
    benchmark: f"{RESULTS}/benchmarks/identify/{{file}}.tsv"
    threads: THREADS
    resources:
        mem_mb=job_mem_mb("identify"),
        runtime=job_runtime("identify"),
    priority: identify_priority
    params:
        spec=job("identify"),
        code=STAGE_CODE["identify"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/identify.py"
