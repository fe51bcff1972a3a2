import shlex
# Figures and tables of each scene, registered for `snakemake --report results/report.html`.
rule shape_picture:
    input: lambda w: PLAN.shape_source(w.scene)
    output: report(f"{RESULTS}/scenes/{{scene}}/shape_{{posture}}.png", caption="../report/shape.rst", category="Shapes", subcategory="{scene}")
    log: f"{RESULTS}/logs/scenes/{{scene}}/shape_{{posture}}.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/shape_{{posture}}.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        posture=lambda w: w.posture,
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/shape_picture.py"


rule shape_vtu:
    input: lambda w: PLAN.shape_source(w.scene)
    output: f"{RESULTS}/scenes/{{scene}}/shape_{{posture}}.vtu"
    log: f"{RESULTS}/logs/scenes/{{scene}}/vtu_{{posture}}.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/vtu_{{posture}}.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        posture=lambda w: w.posture,
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/shape_vtu.py"


rule convergence_figure:
    input: lambda w: [r["identification"] for r in scene_of(w)["runs"]] if scene_of(w)["kind"] == "synthetic" else [scene_of(w)["identification"]]
    output: report(f"{RESULTS}/scenes/{{scene}}/convergence.png", caption="../report/convergence.rst", category="Identification", subcategory="{scene}")
    log: f"{RESULTS}/logs/scenes/{{scene}}/convergence.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/convergence.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/convergence_figure.py"


rule parameter_table:
    input: lambda w: scene_of(w)["identification"]
    output:
        csv=f"{RESULTS}/scenes/{{scene}}/parameters.csv",
        html=report(f"{RESULTS}/scenes/{{scene}}/parameters.html", caption="../report/parameters.rst", category="Identification", subcategory="{scene}"),
    log: f"{RESULTS}/logs/scenes/{{scene}}/parameters.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/parameters.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/parameter_table.py"


rule error_table:
    input: f"{RESULTS}/scenes/{{scene}}/summary.nc"
    output:
        csv=f"{RESULTS}/scenes/{{scene}}/parameter_errors.csv",
        html=report(f"{RESULTS}/scenes/{{scene}}/parameter_errors.html", caption="../report/errors.rst", category="Identification", subcategory="{scene}"),
    log: f"{RESULTS}/logs/scenes/{{scene}}/errors.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/errors.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/error_table.py"


rule diagnostics_table:
    input: lambda w: PLAN.shape_source(w.scene)
    output:
        csv=f"{RESULTS}/scenes/{{scene}}/diagnostics.csv",
        html=report(f"{RESULTS}/scenes/{{scene}}/diagnostics.html", caption="../report/diagnostics.rst", category="Solver diagnostics", subcategory="{scene}"),
    log: f"{RESULTS}/logs/scenes/{{scene}}/diagnostics.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/diagnostics.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/diagnostics_table.py"


rule sensitivity_figure:
    input: lambda w: scene_of(w)["sensitivity"][0]
    output: report(f"{RESULTS}/scenes/{{scene}}/sensitivity.png", caption="../report/sensitivity.rst", category="Sensitivity", subcategory="{scene}")
    log: f"{RESULTS}/logs/scenes/{{scene}}/sensitivity.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/sensitivity_figure.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/sensitivity_figure.py"


rule error_vs_runtime_figure:
    input: f"{RESULTS}/scenes/{{scene}}/summary.nc"
    output: report(f"{RESULTS}/scenes/{{scene}}/error_vs_runtime.png", caption="../report/error_vs_runtime.rst", category="Error against run time", subcategory="{scene}")
    log: f"{RESULTS}/logs/scenes/{{scene}}/error_vs_runtime.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/error_vs_runtime.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/error_vs_runtime_figure.py"


rule stability_map:
    input: f"{RESULTS}/scenes/{{scene}}/summary.nc"
    output: report(f"{RESULTS}/scenes/{{scene}}/stability_map.png", caption="../report/stability.rst", category="Stability", subcategory="{scene}")
    log: f"{RESULTS}/logs/scenes/{{scene}}/stability_map.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/stability_map.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/stability_report.py"


use rule stability_map as stability_table with:
    output:
        csv=f"{RESULTS}/scenes/{{scene}}/stability.csv",
        html=report(f"{RESULTS}/scenes/{{scene}}/stability.html", caption="../report/stability.rst", category="Stability", subcategory="{scene}"),
    log: f"{RESULTS}/logs/scenes/{{scene}}/stability_table.log"
    benchmark: f"{RESULTS}/benchmarks/scenes/{{scene}}/stability_table.tsv"


CONFIG_FILES = " ".join(os.path.relpath(f, workflow.basedir) for f in workflow.overwrite_configfiles)
CONFIG_ARGS = " ".join(shlex.quote(a) for a in workflow.config_settings.config_args or [])


rule results_page:
    input: unpack(lambda w: {name: PLAN.scenes[name]["summary"] for name in PLAN.run_scenes})
    output: "docs/results.md"
    log: f"{RESULTS}/logs/results_page.log"
    benchmark: f"{RESULTS}/benchmarks/results_page.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        commands=["snakemake --cores 2 results_page" + (f" --configfile {CONFIG_FILES}" if CONFIG_FILES else "")
                  + (f" --config {CONFIG_ARGS}" if CONFIG_ARGS else "")],
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/results_page.py"


# The report's first page (workflow/report/workflow.rst inserts it): each scene's findings.
rule report_front_page:
    input: lambda w: [path for _, summary, pictures in PLAN.front_page_scenes() for path in (summary, *pictures)]
    output: f"{RESULTS}/report/front.html"
    log: f"{RESULTS}/logs/report_front_page.log"
    benchmark: f"{RESULTS}/benchmarks/report_front_page.tsv"
    threads: THREADS
    resources:
        mem_mb=DEFAULT_MEM_MB,
        runtime=DEFAULT_MINUTES,
    params:
        scenes=lambda w: PLAN.front_page_scenes(),
        code=CODE,
    conda: "../envs/breastcore.yaml"
    script: "../scripts/front_page.py"
