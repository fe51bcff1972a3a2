# Scene summaries: one dataset per scene gathering what it computed.
rule scene_summary:
    input: lambda w: PLAN.scene_inputs(f"{RESULTS}/scenes/{w.scene}/summary.nc")
    output: f"{RESULTS}/scenes/{{scene}}/summary.nc"
    log: f"{RESULTS}/logs/scenes/{{scene}}/summary.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/summary.tsv"
    params:
        spec=lambda w: scene_of(w),
        scene=lambda w: w.scene,
        datasets=lambda w: PLAN.scene_datasets(w.scene),
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/scene_summary.py"


rule stability:
    input: mesh=lambda w: PLAN.jobs["stability"][f"{RESULTS}/stability/{w.key}.nc"]["mesh"]
    output: f"{RESULTS}/stability/{{key}}.nc"
    log: f"{RESULTS}/logs/stability/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/stability/{{key}}.tsv"
    params:
        spec=job("stability"),
        code=STAGE_CODE["stability"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/stability.py"


rule extreme_guesses:
    input: mesh=lambda w: PLAN.jobs["extreme"][f"{RESULTS}/extreme/{w.key}.nc"]["mesh"]
    output: f"{RESULTS}/extreme/{{key}}.nc"
    log: f"{RESULTS}/logs/extreme/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/extreme/{{key}}.tsv"
    params:
        spec=job("extreme"),
        code=STAGE_CODE["extreme"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/extreme_guesses.py"
