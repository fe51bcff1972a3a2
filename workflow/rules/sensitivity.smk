rule sensitivity:
    input: identification=lambda w: PLAN.jobs["sensitivity"][f"{RESULTS}/sensitivity/{w.key}.nc"]["identification"]
    output: f"{RESULTS}/sensitivity/{{key}}.nc"
    log: f"{RESULTS}/logs/sensitivity/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/sensitivity/{{key}}.tsv"
    params:
        spec=job("sensitivity"),
        code=COMPUTE_CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/sensitivity.py"
