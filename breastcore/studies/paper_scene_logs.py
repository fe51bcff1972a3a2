"""Where a workflow run's identification time goes, read from its logs and benchmarks.

Usage::

    python -m breastcore.studies.paper_scene_logs [--results results] [--since-hash PREFIX]

Reads every ``<results>/identify/*.nc`` (mesh level, failed solves), the job's
Snakemake benchmark (wall seconds; for an identification run in a batch, its share of the
batch's, :func:`~breastcore.pipeline.batches.identification_seconds`) and its log (one line
per Newton iteration and per solve), and prints four tables. A "job" below is one
identification:

- job time per mesh level, with the jobs that had failed trial solves;
- Newton iterations per kind of forward solve: ``warm`` (the target problem solved
  directly from the last accepted equilibrium), ``cold`` (gravity ramp and δ
  continuation from the reference), ``warm fallback`` (a warm start that failed and
  went on by δ continuation); and the modified-Newton steps per job (iterations whose
  step came from the PSD-projected or shifted Hessian, ``mode=project|shift…``);
- where the job time goes: the first cold solve (up to LM's iteration 0) and the time
  outside the log's span (the job's start-up; for a batch, its share of the one start-up), per level (:func:`job_phases`);
- how often the final continuation step (full gravity, target δ, full tolerance)
  failed before a solve succeeded or gave up, which is what
  ``SolverOptions.max_final_attempts`` caps; and, over the solves that gave up after
  more failures than the cap allows, the seconds from their first failed final step to
  the give-up against those up to the cap-th failure (the time the cap saves).

Run it after ``snakemake --cores 2 results_page --configfile config/paper.yaml``;
``--since-hash`` keeps only the datasets written by code whose source hash starts so.
"""

from __future__ import annotations

import argparse
import collections
import re
import statistics
from pathlib import Path

import xarray as xr

from breastcore.forward.options import SolverOptions
from breastcore.pipeline.batches import identification_seconds, log_time
from breastcore.report.text_table import header, print_table

STEP = re.compile(r"breastcore\.forward(?:\.continuation)?: (\S+): step t=(\S+) load=\S+ δ=\S+: (.*) in \d+ iterations")
CONVERGED = re.compile(r"breastcore\.forward(?:\.continuation)?: (\S+): converged in (\d+) iterations \((\d+) continuation"
                       r" steps(?:, (cold|warm|warm fallback) start)?")
GAVE_UP = re.compile(r"forward solve failed \((\S+): ")
#: ``shift`` (the projection's) and, since the inertia shifts, ``shift0.01``, ``shift0.1``.
MODIFIED = re.compile(r"newton it=.* mode=(?:project|shift\S*) ")
FIRST_ITERATE = re.compile(r": identify it=0 ")


def jobs(results: Path, since_hash: str | None):
    """``(key, mesh level, failed solves, wall seconds)`` of every identification job."""
    out, job_seconds = [], identification_seconds(results)
    for path in sorted((results / "identify").glob("*.nc")):
        with xr.open_dataset(path) as ds:
            attrs = dict(ds.attrs)
        if since_hash and not attrs["source_hash"].startswith(since_hash):
            continue
        seconds = job_seconds.get(path.stem)
        seconds = float("nan") if seconds is None else seconds
        out.append((path.stem, attrs["mesh_level"], int(attrs["failed_solves"]), seconds))
    return out


def solve_kinds(log: Path, cap: int = SolverOptions().max_final_attempts):
    """Newton iterations per solve kind, final-step failures before each outcome, retry time.

    Returns ``(iterations, counts, outcomes, retry)``; ``retry["after first"]`` and
    ``retry["up to cap"]`` sum, over the solves that gave up after more than ``cap``
    failed final steps, the seconds from the first failure to the give-up and to the
    ``cap``-th failure.
    """
    iterations, counts = collections.Counter(), collections.Counter()
    outcomes = collections.Counter()                        # (outcome, final-step failures) -> solves
    retry = collections.Counter()
    first_t, final_failures, failed_at = {}, collections.Counter(), collections.defaultdict(list)
    for line in log.read_text(errors="replace").splitlines():
        if m := STEP.search(line):
            posture, t, message = m.group(1), float(m.group(2)), m.group(3)
            first_t.setdefault(posture, t)
            if t == 2.0 and not message.startswith("converged"):
                final_failures[posture] += 1
                failed_at[posture].append(log_time(line))
        elif m := CONVERGED.search(line):
            posture, its, steps = m.group(1), int(m.group(2)), int(m.group(3))
            # Logs since the start kind was written say it; older ones (every solve then had a
            # δ phase) tell it from the continuation: one step is warm, a start at t ≤ 1 cold.
            kind = m.group(4) or ("warm" if steps == 1 else "cold" if first_t.get(posture, 9.0) <= 1.0
                                  else "warm fallback")
            iterations[kind] += its
            counts[kind] += 1
            outcomes[("converged", final_failures.pop(posture, 0))] += 1
            first_t.pop(posture, None)
            failed_at.pop(posture, None)
        elif m := GAVE_UP.search(line):
            posture = m.group(1)
            outcomes[("gave up", final_failures.pop(posture, 0))] += 1
            first_t.pop(posture, None)
            times = failed_at.pop(posture, [])
            if len(times) > cap:
                retry["after first"] += (log_time(line) - times[0]).total_seconds()
                retry["up to cap"] += (times[cap - 1] - times[0]).total_seconds()
    return iterations, counts, outcomes, retry


def job_phases(log: Path, seconds: float):
    """``(first solve, outside the log)`` seconds of one identification job.

    The first is from the log's first line to LM's iteration 0, i.e. the cold solve at the
    start; the second is the job's ``benchmark:`` time less its log's span: the process's
    start-up (interpreter, imports, numba's cached kernels) and what follows the last line.
    """
    lines = [line for line in log.read_text(errors="replace").splitlines() if line[:2] == "20"]
    start = log_time(lines[0])
    first = next((log_time(line) for line in lines if FIRST_ITERATE.search(line)), start)
    return (first - start).total_seconds(), seconds - (log_time(lines[-1]) - start).total_seconds()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--results", default="results", type=Path)
    parser.add_argument("--since-hash", default=None)
    args = parser.parse_args(argv)
    header("paper_scene_logs")
    rows = jobs(args.results, args.since_hash)
    by_level = collections.defaultdict(list)
    for row in rows:
        by_level[row[1]].append(row)
    table, kinds = [], collections.defaultdict(lambda: [collections.Counter(), collections.Counter()])
    outcomes, retry, modified = collections.Counter(), collections.Counter(), collections.Counter()
    phases = collections.defaultdict(list)
    seconds_of = {r[0]: r[3] for r in rows}
    for level, level_rows in by_level.items():
        times = [r[3] for r in level_rows]
        failed = [r[3] for r in level_rows if r[2] > 0]
        table.append([level, len(level_rows), f"{sum(times):.0f}", f"{statistics.median(times):.1f}",
                      f"{statistics.fmean(times):.1f}", f"{max(times):.0f}", len(failed), f"{sum(failed):.0f}"])
        for key, *_ in level_rows:
            log = args.results / "logs" / "identify" / f"{key}.log"
            if log.exists():
                its, counts, outs, seconds = solve_kinds(log)
                kinds[level][0].update(its)
                kinds[level][1].update(counts)
                outcomes.update(outs)
                retry.update(seconds)
                modified[level] += len(MODIFIED.findall(log.read_text()))
                phases[level].append((seconds_of[key], *job_phases(log, seconds_of[key])))
    total = sum(r[3] for r in rows)
    table.append(["all", len(rows), f"{total:.0f}", "", "", "", sum(r[2] > 0 for r in rows),
                  f"{sum(r[3] for r in rows if r[2] > 0):.0f}"])
    print_table(["level", "jobs", "job time (s)", "median (s)", "mean (s)", "max (s)", "jobs with failed solves",
                 "their time (s)"], table, "Identification job time per mesh level")
    print_table(["level"] + [f"{k} solves (Newton its)" for k in ("warm", "cold", "warm fallback")]
                + ["modified steps per job"],
                [[level] + [f"{c[1][k]} ({c[0][k]})" for k in ("warm", "cold", "warm fallback")]
                 + [f"{modified[level] / len(by_level[level]):.0f}"]
                 for level, c in kinds.items()], "Forward solves by kind")
    print_table(["level", "job time (s)", "first cold solve (s)", "share", "outside the log (s)", "share",
                 "outside the log, median per job (s)"],
                [[level, f"{sum(p[0] for p in ps):.0f}", f"{sum(p[1] for p in ps):.0f}",
                  f"{sum(p[1] for p in ps) / sum(p[0] for p in ps):.1%}", f"{sum(p[2] for p in ps):.0f}",
                  f"{sum(p[2] for p in ps) / sum(p[0] for p in ps):.1%}", f"{statistics.median(p[2] for p in ps):.2f}"]
                 for level, ps in [*phases.items(), ("all", [p for ps in phases.values() for p in ps])]],
                "Where the job time goes")
    print_table(["outcome", "final-step failures before it", "solves"],
                [[o, k, n] for (o, k), n in sorted(outcomes.items())], "Final continuation step")
    cap = SolverOptions().max_final_attempts
    print(f"Solves that gave up after more than {cap} failed final steps: "
          f"{retry['after first']:.0f} s from the first failure to the give-up, "
          f"{retry['up to cap']:.0f} s up to failure {cap}, so the cap saves "
          f"{retry['after first'] - retry['up to cap']:.0f} s.")


if __name__ == "__main__":
    main()
