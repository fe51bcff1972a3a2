def _identify_spec(w):
    return PLAN.jobs["identify"][f"{RESULTS}/identify/{w.key}.nc"]


rule identify:
    input:
        measurements=lambda w: _identify_spec(w)["measurements"],
        mesh=lambda w: _identify_spec(w)["mesh"],
    output: f"{RESULTS}/identify/{{key}}.nc"
    log: f"{RESULTS}/logs/identify/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/identify/{{key}}.tsv"
    params:
        spec=job("identify"),
        code=CODE,
    script: "../scripts/identify.py"
