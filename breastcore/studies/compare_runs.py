"""Two runs of the same identification jobs, level by level: job time and the work done.

Usage::

    python -m breastcore.studies.compare_runs --before <results of the earlier run> [--after results] [--paper-only]

Jobs are matched by output name (``results/identify/<hash>.nc``: the hash is the job's
spec, so the same guess, mesh and options). Per mesh level it prints the job time summed
over the ``benchmark:`` files of the jobs present in both runs (an identification run in a
batch counts its share, :func:`~breastcore.pipeline.batches.identification_seconds`), and the median of the
per-job ratios; then, over the datasets present in both, the LM iterations, forward
solves and branch restarts, and how many estimates agree to ``--rtol``. With
``--paper-only``, only the identify jobs of ``config/paper.yaml`` (545) are compared, not
those of the evidence scenes that share the folder.
"""

from __future__ import annotations

import argparse
import statistics
from collections import defaultdict
from pathlib import Path

import numpy as np

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.batches import identification_seconds
from breastcore.report.text_table import header, print_table


def compare(before: Path, after: Path, rtol: float, only=None):
    """``{level: {counter: [values]}}`` over the identify jobs both runs have (and in ``only``, a set of names)."""
    levels = defaultdict(lambda: defaultdict(list))
    seconds_before, seconds_after = identification_seconds(before), identification_seconds(after)
    for new_path in sorted((after / "identify").glob("*.nc")):
        old_path = before / "identify" / new_path.name
        if not old_path.exists() or (only is not None and new_path.name not in only):
            continue
        with open_dataset(new_path) as new, open_dataset(old_path) as old:
            row = levels[new.attrs["mesh_level"]]
            for name in ("iterations", "forward_solves", "branch_restarts"):
                row[f"{name} before"].append(int(old.attrs[name]))
                row[f"{name} after"].append(int(new.attrs[name]))
            row["same estimate"].append(bool(np.allclose(new["estimate"].values, old["estimate"].values,
                                                         rtol=rtol, atol=0)))
        times = seconds_before.get(new_path.stem), seconds_after.get(new_path.stem)
        if None not in times:
            row["seconds"].append(times)
    return levels


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", required=True, help="results folder of the earlier run")
    parser.add_argument("--after", default="results", help="results folder of the later run")
    parser.add_argument("--rtol", type=float, default=1e-6, help="estimates agreeing to this count as the same")
    parser.add_argument("--paper-only", action="store_true", help="only the identify jobs of config/paper.yaml")
    args = parser.parse_args(argv)
    header("compare_runs")
    only = None
    if args.paper_only:
        from breastcore.pipeline.plan import plan_from_files
        only = {Path(path).name for path in plan_from_files("config.yaml", "config/paper.yaml").jobs["identify"]}
    levels = compare(Path(args.before), Path(args.after), args.rtol, only)
    time_rows, work_rows, pairs = [], [], []
    for level, row in sorted(levels.items()):
        seconds = row["seconds"]
        pairs += seconds
        old, new = sum(t[0] for t in seconds), sum(t[1] for t in seconds)
        time_rows.append([level, len(seconds), f"{old:.0f}", f"{new:.0f}", f"{new / old:.2f}",
                          f"{statistics.median(b / a for a, b in seconds):.2f}"])
        work_rows.append([level, len(row["same estimate"])]
                         + [f"{sum(row[f'{n} before'])} → {sum(row[f'{n} after'])}"
                            for n in ("iterations", "forward_solves", "branch_restarts")]
                         + [sum(row["same estimate"])])
    old, new = sum(t[0] for t in pairs), sum(t[1] for t in pairs)
    time_rows.append(["all", len(pairs), f"{old:.0f}", f"{new:.0f}", f"{new / old:.2f}",
                      f"{statistics.median(b / a for a, b in pairs):.2f}"])
    print_table(["level", "jobs", "before s", "after s", "ratio", "median per-job ratio"], time_rows,
                title="Identification job time, the same jobs in both runs")
    print_table(["level", "datasets", "LM iterations", "forward solves", "branch restarts",
                 f"same estimate (rtol {args.rtol:g})"], work_rows, title="Work done")


if __name__ == "__main__":
    main()
