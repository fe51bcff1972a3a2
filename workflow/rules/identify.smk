# One identification per job (rule identify), or several that differ only in their initial
# guess (a Table-1 cell's starts) in one job (rules identify_batch_<key>, made below from
# breastcore.pipeline.batches): one process start-up for `identify_batch` of them. Each writes
# the file, log and dataset it writes as a job of its own. A rule without wildcards wins over
# `identify` for its files.
#
# A file made by one kind of job is not rerun by the other. Snakemake reruns a file when
# the params it compares or the rule's code changed. The specs are a param derived from the
# outputs, which it does not compare (the path carries their hash). As a script rule's code
# it records the `script:` line, indentation included: hence the `if True:` that indents
# `identify` as deep as the batch rules in their loop.
if True:
    rule identify:
        input:
            measurements=lambda w: identify_spec(w)["measurements"],
            mesh=lambda w: identify_spec(w)["mesh"],
        output: f"{RESULTS}/identify/{{file}}.nc"
        log: f"{RESULTS}/logs/identify/{{file}}.log"
        benchmark: f"{RESULTS}/benchmarks/identify/{{file}}.tsv"
        threads: THREADS
        resources:
            mem_mb=job_mem_mb("identify"),
            runtime=job_runtime("identify"),
        priority: identify_priority
        params:
            specs=identify_specs,
            code=STAGE_CODE["identify"],
        conda: "../envs/breastcore.yaml"
        script: "../scripts/identify.py"

for _batch, _paths in IDENTIFY_BATCHES.items():
    _first = PLAN.jobs["identify"][_paths[0]]
    _level = PLAN.jobs["mesh"][_first["mesh"]].get("level")

    rule:
        name: f"identify_batch_{_batch}"
        input:
            measurements=_first["measurements"],
            mesh=_first["mesh"],
        output: _paths
        log: [f"{RESULTS}/logs/identify/{os.path.basename(path)[:-3]}.log" for path in _paths]
        benchmark: batch_benchmark(RESULTS, _level, _batch)
        threads: THREADS
        resources:
            mem_mb=mem_mb(_level),
            runtime=len(_paths) * runtime_minutes("identify", _level),
        priority: LEVEL_PRIORITY.get(_level, 0)
        params:
            specs=identify_specs,
            code=STAGE_CODE["identify"],
        conda: "../envs/breastcore.yaml"
        script: "../scripts/identify.py"
