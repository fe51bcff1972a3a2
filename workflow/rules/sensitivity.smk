rule sensitivity:
    input: identification=lambda w: PLAN.jobs["sensitivity"][f"{RESULTS}/sensitivity/{w.file}.nc"]["identification"]
    output: f"{RESULTS}/sensitivity/{{file}}.nc"
    log: f"{RESULTS}/logs/sensitivity/{{file}}.log"
    benchmark: f"{RESULTS}/benchmarks/sensitivity/{{file}}.tsv"
    # One core: the finite version's 2n re-identifications run one after the other, beside
    # the scene's other jobs (priority). With 2 forked processes it could only start once
    # both cores were free, i.e. last, and its uneven halves left one core idle for minutes.
    threads: THREADS
    resources:
        mem_mb=job_mem_mb("sensitivity"),
        runtime=job_runtime("sensitivity"),
    priority: sensitivity_priority
    params:
        spec=job("sensitivity"),
        code=STAGE_CODE["sensitivity"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/sensitivity.py"
