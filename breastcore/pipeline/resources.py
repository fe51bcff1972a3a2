"""What each workflow job asks a scheduler for: threads, memory and run time.

Snakemake passes these to a cluster executor (SLURM: ``--cpus-per-task``, ``--mem``,
``--time``); on one machine ``--cores`` and ``--resources mem_mb=...`` cap them. They are
declared caps, not predictions: a job that outgrows its request is killed by the
scheduler, so each is several times the largest measured on the paper's levels
(``results/benchmarks/<stage>/*.tsv`` of the calibration and paper scenes, 2026-12-02:
every job up to the reference level peaked below 0.41 GB, an identification on
ultra-thin took up to 6 min, a calibration job up to 7 min).
"""

from __future__ import annotations

#: Every job is single-threaded: PARDISO runs on one thread (see
#: :data:`breastcore.linalg.pardiso.PARDISO_THREADS_ENV`) and the workflow runs one job per core.
THREADS = 1

#: Memory request, MB, per mesh level; levels not listed (and patient measurements) get
#: :data:`DEFAULT_MEM_MB`. fine50k: ≤ 4 GB per posture is the goal (docs/benchmarks.md).
LEVEL_MEM_MB = {"reference": 1500, "fine10k": 2500, "fine50k": 6000}
DEFAULT_MEM_MB = 1000

#: Run time request, minutes, of one solve-sized job per level.
LEVEL_MINUTES = {"coarse": 5, "medium": 5, "medium-thin": 10, "thin": 10, "very-thin": 20, "ultra-thin": 30,
                 "reference": 60, "fine10k": 60, "fine50k": 120}
DEFAULT_MINUTES = 10

#: How many solve-sized units a job of each stage is. The finite sensitivity is 2 × 6
#: re-identifications plus the base; stability chunks and extreme guesses run many solves.
STAGE_FACTOR = {"mesh": 1, "solve": 1, "measure": 1, "identify": 1, "sensitivity": 1, "finite_sensitivity": 13,
                "stability": 4, "extreme": 4, "calibrate": 2, "uniqueness": 1}


def mem_mb(level) -> int:
    """Memory request of a job on mesh ``level`` (None: no mesh of its own), MB."""
    return LEVEL_MEM_MB.get(level, DEFAULT_MEM_MB)


def runtime_minutes(stage, level) -> int:
    """Run-time request of a job of ``stage`` on mesh ``level``, minutes.

    ``stage`` is a workflow stage, or ``finite_sensitivity`` for the ±10 % re-identifications.
    """
    if stage not in STAGE_FACTOR:
        raise ValueError(f"unknown stage {stage!r}; stages: {', '.join(STAGE_FACTOR)}")
    return STAGE_FACTOR[stage] * LEVEL_MINUTES.get(level, DEFAULT_MINUTES)
