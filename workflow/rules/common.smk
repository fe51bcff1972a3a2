# The job plan (breastcore.pipeline.plan) and helpers shared by the rules.
import os

from breastcore import STAGES, source_hash, stage_hash
from breastcore.model.mesh import LEVEL_NODE_COUNTS
from breastcore.pipeline.batches import batch_benchmark, identify_batches
from breastcore.pipeline.plan import Plan
from breastcore.pipeline.resources import DEFAULT_MEM_MB, DEFAULT_MINUTES, THREADS, mem_mb, runtime_minutes

PLAN = Plan(config)
RESULTS = PLAN.results
# A param of every rule, so that changed code reruns what it affects: each compute rule
# hashes the modules its stage imports (breastcore.stages.<stage>, logs, keys), so an edit
# of stability.py reruns the stability chunks only; the report rules hash the whole package.
STAGE_CODE = {stage: stage_hash(stage) for stage in STAGES}
IDENTIFY_BATCHES = identify_batches(PLAN, PLAN.identify_batch)
CODE = source_hash()

wildcard_constraints:
    name="[^/]+",
    file="[A-Za-z0-9_.+-]*[0-9a-f]{10}",
    scene="[A-Za-z][A-Za-z0-9_-]*",
    posture="[A-Za-z][A-Za-z0-9_-]*",


def job(stage):
    """Params function: the spec of the job that writes this output."""
    return lambda wildcards, output: PLAN.jobs[stage][output[0]]


def scene_of(wildcards):
    return PLAN.scene(wildcards.scene)


# Scheduling only, no effect on any result. A finite sensitivity (one long single-core
# job) and the identification it needs go first, so that it runs beside the rest instead
# of last; then the finer meshes first (longest jobs first), so that no long job is left
# alone at the end while the other core idles.
# Rule priorities do not pass to a job's inputs (only `--prioritize` targets do), so the
# short mesh, solve and measure jobs that the identifications wait on rank above them all:
# otherwise a ready identification of higher priority always wins, and a scene whose data
# is not measured yet waits until every other identification has run.
UPSTREAM_PRIORITY = 1000
FINITE_SENSITIVITY_BASES = {spec["identification"] for spec in PLAN.jobs["sensitivity"].values() if spec["finite"]}
LEVEL_PRIORITY = {level: rank for rank, level in enumerate(LEVEL_NODE_COUNTS)}


def identify_priority(wildcards):
    path = f"{RESULTS}/identify/{wildcards.file}.nc"
    if path in FINITE_SENSITIVITY_BASES:
        return 100
    return LEVEL_PRIORITY.get(PLAN.jobs["mesh"][identify_spec(wildcards)["mesh"]].get("level"), 0)


def sensitivity_priority(wildcards):
    return 100 if PLAN.jobs["sensitivity"][f"{RESULTS}/sensitivity/{wildcards.file}.nc"]["finite"] else 0


def identify_spec(wildcards):
    return PLAN.jobs["identify"][f"{RESULTS}/identify/{wildcards.file}.nc"]


def identify_specs(wildcards, output):
    """Params function of the identify rules: the spec of each output, in order."""
    return [PLAN.jobs["identify"][path] for path in output]


def job_level(stage):
    """The mesh level of the job behind a wildcard match (None: a patient's measurements)."""
    return lambda wildcards: PLAN.level_of(f"{RESULTS}/{stage}/{wildcards.file}.nc")


def job_mem_mb(stage):
    """Resources function: the job's memory request, MB (breastcore.pipeline.resources)."""
    level = job_level(stage)
    return lambda wildcards: mem_mb(level(wildcards))


def job_runtime(stage):
    """Resources function: the job's run-time request, minutes (breastcore.pipeline.resources)."""
    level = job_level(stage)
    if stage == "sensitivity":
        return lambda wildcards: runtime_minutes(
            "finite_sensitivity" if PLAN.jobs["sensitivity"][f"{RESULTS}/sensitivity/{wildcards.file}.nc"]["finite"]
            else "sensitivity", level(wildcards))
    return lambda wildcards: runtime_minutes(stage, level(wildcards))
