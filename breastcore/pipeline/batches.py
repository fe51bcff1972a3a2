"""Identifications run together in one workflow job: one process, one start-up, several guesses.

A Table-1 cell of the paper scene is ten identifications that differ only in their initial
guess. As ten jobs, each pays a Python start-up, the imports and the compiled kernels' load
(about 2-3 s against 4-30 s of work), and Snakemake schedules ten jobs instead of one. A batch
runs them one after the other in one job; each still writes its own dataset, with the same
path, content and log as a job of its own (``tests/pipeline/test_batches.py``).
"""

from __future__ import annotations

import datetime
import logging
import re
from pathlib import Path

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import benchmark_seconds, log_to

logger = logging.getLogger(__name__)


def _context(spec) -> str:
    """What a batch's identifications share: everything in the spec but the initial guess."""
    return spec_key({key: value for key, value in spec.items() if key != "initial"})


def identify_batches(plan, size: int) -> dict:
    """The identification jobs of ``plan`` that run in batches of at most ``size``.

    Parameters
    ----------
    plan : Plan
    size : int
        Most identifications per job; 1 = one job each (no batches).

    Returns
    -------
    dict
        ``{batch key: [output path, ...]}``, each list of two or more identifications with the
        same measurements, mesh, constants, solver and options, in plan order. Left out (one
        job each): identifications alone in their context, the last one of a context when it is
        left over, and the base of a finite sensitivity, which is scheduled first so that that
        long job starts early.
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
    """The ``benchmark:`` file of batch ``key`` on mesh ``level`` (one for the whole batch)."""
    return f"{results}/benchmarks/identify/batch-{level}-{key}.tsv"


#: The first line of an identification's log: which job ran it (``identify`` or ``identify_batch_<key>``).
JOB_LINE = re.compile(r"identification (\d+) of (\d+) in job (\S+)$")


def run_identifications(specs, measurements, mesh, outputs, logs, job):
    """Run the identifications of one workflow job, one after the other, each with its own log.

    Parameters
    ----------
    specs : list of dict
        The identify job specs (:meth:`Plan.identify`), one per output.
    measurements, mesh : str
        The measurement and mesh datasets they share.
    outputs, logs : list of str
        Each identification's dataset and log.
    job : str
        The rule's name, recorded first in each log (:data:`JOB_LINE`), where
        :func:`identification_seconds` finds a batch's members.
    """
    from breastcore.stages.identify import run_identify      # not at the Snakefile's parse: the model's imports

    for index, (spec, out, log) in enumerate(zip(specs, outputs, logs, strict=True), start=1):
        with log_to(log):
            logger.info("identification %d of %d in job %s", index, len(specs), job)
            run_identify(spec, measurements, mesh, out, spec_key(spec))


def _stamp(line):
    return datetime.datetime.strptime(line[:23], "%Y-%m-%d %H:%M:%S,%f")


def identification_seconds(results) -> dict:
    """Job seconds of each identification in the results folder ``results``: ``{file stem: s}``.

    One that ran alone has its job's ``benchmark:`` seconds. One that ran in a batch has a
    share of its batch's seconds in proportion to its log's time span, so that the shares sum
    to the batch's seconds (its start-up shared the same way). Left out: identifications with
    neither (their job's benchmark or log is missing).
    """
    folder = Path(results)
    seconds, members = {}, {}
    for log in sorted((folder / "logs" / "identify").glob("*.log")):
        lines = log.read_text().splitlines()
        match = JOB_LINE.search(lines[0]) if lines else None
        if match and match.group(3).startswith("identify_batch_"):
            span = (_stamp(lines[-1]) - _stamp(lines[0])).total_seconds()
            members.setdefault(match.group(3).removeprefix("identify_batch_"), []).append((log.stem, span))
    for bench in sorted((folder / "benchmarks" / "identify").glob("*.tsv")):
        if not bench.stem.startswith("batch-"):
            seconds[bench.stem] = benchmark_seconds(bench)
            continue
        batch = members.get(bench.stem.rsplit("-", 1)[-1], [])
        total = sum(span for _, span in batch)
        for stem, span in batch:
            seconds[stem] = benchmark_seconds(bench) * (span / total if total > 0 else 1 / len(batch))
    return seconds
