# Scene summaries: one dataset per scene gathering what it computed.
rule scene_summary:
    input: lambda w: PLAN.scene_inputs(f"{RESULTS}/scenes/{w.scene}/summary.nc")
    output: f"{RESULTS}/scenes/{{scene}}/summary.nc"
    log: f"{RESULTS}/logs/scenes/{{scene}}/summary.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/summary.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        spec=lambda w: scene_of(w),
        scene=lambda w: w.scene,
        datasets=lambda w: PLAN.scene_datasets(w.scene),
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/scene_summary.py"


rule stability:
    input: mesh=lambda w: PLAN.jobs["stability"][f"{RESULTS}/stability/{w.file}.nc"]["mesh"]
    output: f"{RESULTS}/stability/{{file}}.nc"
    log: f"{RESULTS}/logs/stability/{{file}}.log"
    benchmark: f"{RESULTS}/benchmarks/stability/{{file}}.tsv"
    threads: THREADS
    resources:
        mem_mb=job_mem_mb("stability"),
        runtime=job_runtime("stability"),
    params:
        spec=job("stability"),
        code=STAGE_CODE["stability"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/stability.py"


rule extreme_guesses:
    input: mesh=lambda w: PLAN.jobs["extreme"][f"{RESULTS}/extreme/{w.file}.nc"]["mesh"]
    output: f"{RESULTS}/extreme/{{file}}.nc"
    log: f"{RESULTS}/logs/extreme/{{file}}.log"
    benchmark: f"{RESULTS}/benchmarks/extreme/{{file}}.tsv"
    threads: THREADS
    resources:
        mem_mb=job_mem_mb("extreme"),
        runtime=job_runtime("extreme"),
    params:
        spec=job("extreme"),
        code=STAGE_CODE["extreme"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/extreme_guesses.py"
