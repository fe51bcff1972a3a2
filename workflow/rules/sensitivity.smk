rule sensitivity:
    input: identification=lambda w: PLAN.jobs["sensitivity"][f"{RESULTS}/sensitivity/{w.key}.nc"]["identification"]
    output: f"{RESULTS}/sensitivity/{{key}}.nc"
    log: f"{RESULTS}/logs/sensitivity/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/sensitivity/{{key}}.tsv"
    threads: 2      # the finite version's 2n re-identifications run in forked processes (scaled down to --cores)
    params:
        spec=job("sensitivity"),
        code=COMPUTE_CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/sensitivity.py"
