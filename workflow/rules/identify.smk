rule identify:
    input:
        measurements=lambda w: identify_spec(w)["measurements"],
        mesh=lambda w: identify_spec(w)["mesh"],
    output: f"{RESULTS}/identify/{{key}}.nc"
    log: f"{RESULTS}/logs/identify/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/identify/{{key}}.tsv"
    priority: identify_priority
    params:
        spec=job("identify"),
        code=STAGE_CODE["identify"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/identify.py"
