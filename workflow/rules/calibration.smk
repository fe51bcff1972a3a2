# The calibration scene of the Chassaignac coefficient c (breastcore.calibration_plan):
# per c, one calibrate job per level (cold solves at the truth and the box corners) and
# one uniqueness probe; its identifications are the ordinary identify jobs.
rule calibrate:
    input: mesh=lambda w: PLAN.jobs["calibrate"][f"{RESULTS}/calibrate/{w.key}.nc"]["mesh"]
    output: f"{RESULTS}/calibrate/{{key}}.nc"
    log: f"{RESULTS}/logs/calibrate/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/calibrate/{{key}}.tsv"
    # Finer levels first: they are the longest jobs (see identify_priority).
    priority: lambda w: LEVEL_PRIORITY.get(PLAN.jobs["calibrate"][f"{RESULTS}/calibrate/{w.key}.nc"]["level"], 0)
    params:
        spec=job("calibrate"),
        code=STAGE_CODE["calibrate"],
    conda: "../envs/breastcore.yaml"
    script: "../scripts/calibrate.py"


rule uniqueness:
    input: mesh=lambda w: PLAN.jobs["uniqueness"][f"{RESULTS}/uniqueness/{w.key}.nc"]["mesh"]
    output: f"{RESULTS}/uniqueness/{{key}}.nc"
    log: f"{RESULTS}/logs/uniqueness/{{key}}.log"
    benchmark: f"{RESULTS}/benchmarks/uniqueness/{{key}}.tsv"
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
    params:
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/calibration_figure.py"
