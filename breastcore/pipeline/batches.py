"""Identifications run together in one workflow job: one process, one start-up, several guesses.

A Table-1 cell of the paper scene is ten identifications that differ only in their initial
guess. As ten jobs, each pays a Python start-up, the imports and the compiled kernels' load
(about 2-3 s against 4-30 s of work), and Snakemake schedules ten jobs instead of one. A batch
(rule ``identify_batch_<key>``) runs them one after the other in one process
(:func:`breastcore.stages.identify.run_identifications`); each still writes its own dataset,
equal value for value to a lone job's, and its own log (``tests/pipeline/test_batches.py``).
"""

from __future__ import annotations

import datetime
import re
from collections import defaultdict
from pathlib import Path

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import benchmark_seconds

#: The first line of an identification's log (:func:`breastcore.stages.identify.run_identifications`):
#: which job ran it, ``identify`` or ``identify_batch_<key>``.
JOB_LINE = re.compile(r"identification (\d+) of (\d+) in job (\S+)$")
BATCH_RULE = "identify_batch_"


def _context(spec) -> str:
    """What a batch's identifications share: everything in the spec but the initial guess."""
    return spec_key({key: value for key, value in spec.items() if key != "initial"})


def identify_batches(plan, size: int) -> dict:
    """The identification jobs of ``plan`` that run in batches of at most ``size``.

    Parameters
    ----------
    plan : breastcore.pipeline.plan.Plan
        The workflow's jobs.
    size : int
        Most identifications per job (config key ``identify_batch``); 1 = one job each.

    Returns
    -------
    dict
        ``{batch key: [output path, ...]}``, each list of two or more identifications with the
        same measurements, mesh, constants, solver and options, in plan order; the key is a
        hash of the list. Left out (one job each): identifications alone in their context, the
        last one of a context when it is left over, and the base of a finite sensitivity, which
        is scheduled first so that that long job starts early.

    Raises
    ------
    ValueError
        ``size`` < 1.
    """
    if size < 1:
        raise ValueError(f"identify_batch = {size}: the number of identifications per job must be at least 1")
    first = {spec["identification"] for spec in plan.jobs["sensitivity"].values() if spec["finite"]}
    contexts = {}
    for path, spec in plan.jobs["identify"].items():
        if path not in first:
            contexts.setdefault(_context(spec), []).append(path)
    batches = {}
    for paths in contexts.values():
        for i in range(0, len(paths), size):
            chunk = paths[i:i + size]
            if len(chunk) > 1:
                batches[spec_key(chunk)] = chunk
    return batches


def batch_benchmark(results, level, key) -> str:
    """The ``benchmark:`` file of batch ``key`` on mesh ``level``, one for the whole batch.

    ``results/benchmarks/identify/batch-<level>-<key>.tsv``, under the results folder ``results``.
    """
    return f"{results}/benchmarks/identify/batch-{level}-{key}.tsv"


def log_time(line):
    """The time of a workflow log line (``2026-12-03 12:07:17,100 DEBUG ...``, :func:`~breastcore.pipeline.logs.log_to`)."""
    return datetime.datetime.strptime(line[:23], "%Y-%m-%d %H:%M:%S,%f")


def identification_seconds(results) -> dict:
    """Job seconds of each identification in a results folder.

    Parameters
    ----------
    results : str or Path
        A workflow's results folder (its ``benchmarks/identify`` and ``logs/identify``).

    Returns
    -------
    dict
        ``{file stem: s}``, e.g. ``{"coarse-lm-0d07f42fda": 4.2}``. An identification whose log
        says it ran alone (or names no job: runs before batches) has its own job's
        ``benchmark:`` seconds. One whose log names a batch has a share of that batch's
        seconds in proportion to its log's time span, so that the shares sum to the batch's
        seconds (the start-up shared the same way). Left out: those without a benchmark file
        (a failed job writes none).
    """
    folder = Path(results)
    batch_of, span = {}, {}
    for log in sorted((folder / "logs" / "identify").glob("*.log")):
        lines = [line for line in log.read_text(errors="replace").splitlines() if line[:2] == "20"]
        job = JOB_LINE.search(lines[0]) if lines else None
        if job and job.group(3).startswith(BATCH_RULE):
            batch_of[log.stem] = job.group(3).removeprefix(BATCH_RULE)
            span[log.stem] = (log_time(lines[-1]) - log_time(lines[0])).total_seconds()
    members = defaultdict(list)
    for stem, key in batch_of.items():
        members[key].append(stem)
    seconds = {}
    for bench in sorted((folder / "benchmarks" / "identify").glob("*.tsv")):
        if not bench.stem.startswith("batch-"):
            if bench.stem not in batch_of:        # a lone job's, not one left from before a batch remade it
                seconds[bench.stem] = benchmark_seconds(bench)
            continue
        stems = members.get(bench.stem.rsplit("-", 1)[-1], [])
        batch, total = benchmark_seconds(bench), sum(span[stem] for stem in stems)
        for stem in stems:
            seconds[stem] = batch * (span[stem] / total if total > 0 else 1 / len(stems))
    return seconds
