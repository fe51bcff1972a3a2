rule sensitivity:
    input: identification=lambda w: PLAN.jobs["sensitivity"][f"{RESULTS}/sensitivity/{w.key}.nc"]["identification"]
    output: f"{RESULTS}/sensitivity/{{key}}.nc"
    log: f"{RESULTS}/logs/sensitivity/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/sensitivity/{{key}}.tsv"
    # One core: the finite version's 2n re-identifications run one after the other, beside
    # the scene's other jobs (priority). With 2 forked processes it could only start once
    # both cores were free, i.e. last, and its uneven halves left one core idle for minutes.
    threads: 1
    priority: sensitivity_priority
    params:
        spec=job("sensitivity"),
        code=STAGE_CODE["sensitivity"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/sensitivity.py"
