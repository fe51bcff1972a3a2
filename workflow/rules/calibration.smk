# The calibration scene of the Chassaignac coefficient c (breastcore.pipeline.calibration_plan):
# per c, one calibrate job per level (cold solves at the truth and the box corners) and
# one uniqueness probe; its identifications are the ordinary identify jobs.
rule calibrate:
    input: mesh=lambda w: PLAN.jobs["calibrate"][f"{RESULTS}/calibrate/{w.file}.nc"]["mesh"]
    output: f"{RESULTS}/calibrate/{{file}}.nc"
    log: f"{RESULTS}/logs/calibrate/{{file}}.log"
    benchmark: f"{RESULTS}/benchmarks/calibrate/{{file}}.tsv"
    # Finer levels first: they are the longest jobs (see identify_priority).
    priority: lambda w: LEVEL_PRIORITY.get(PLAN.jobs["calibrate"][f"{RESULTS}/calibrate/{w.file}.nc"]["level"], 0)
    threads: THREADS
    resources:
        mem_mb=job_mem_mb("calibrate"),
        runtime=job_runtime("calibrate"),
    params:
        spec=job("calibrate"),
        code=STAGE_CODE["calibrate"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/calibrate.py"


rule uniqueness:
    input: mesh=lambda w: PLAN.jobs["uniqueness"][f"{RESULTS}/uniqueness/{w.file}.nc"]["mesh"]
    output: f"{RESULTS}/uniqueness/{{file}}.nc"
    log: f"{RESULTS}/logs/uniqueness/{{file}}.log"
    benchmark: f"{RESULTS}/benchmarks/uniqueness/{{file}}.tsv"
    threads: THREADS
    resources:
        mem_mb=job_mem_mb("uniqueness"),
        runtime=job_runtime("uniqueness"),
    params:
        spec=job("uniqueness"),
        code=STAGE_CODE["uniqueness"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/uniqueness.py"


rule calibration_figure:
    input: f"{RESULTS}/scenes/{{scene}}/summary.nc"
    output: report(f"{RESULTS}/scenes/{{scene}}/table2_residual.png", caption="../report/calibration.rst", category="Calibration", subcategory="{scene}")
    log: f"{RESULTS}/logs/scenes/{{scene}}/table2_residual.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/table2_residual.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/calibration_figure.py"
